// Camera and pacing: orbit/zoom (three.js OrbitControls), following a subject, and the
// frame-time budget that keeps a 60 Hz stream with skinned characters smooth in a browser
// that renders in software.
import * as THREE from 'three';
import { OrbitControls } from './vendor/three/addons/controls/OrbitControls.js';

export class CameraRig {
  constructor(camera, element) {
    this.camera = camera;
    this.orbit = new OrbitControls(camera, element);
    this.orbit.enableDamping = false;
    // Once the user has moved the camera, layouts no longer reframe it (until "reset view").
    this.userMoved = false;
    this.orbit.addEventListener('start', () => { this.userMoved = true; });
    this.followed = null; // a function returning the followed point, or null
    this.lastFollowed = null;
  }

  /** Frames `center` from `position` (a layout's choice), unless the user has taken over. */
  frame(position, center, force = false) {
    if (this.userMoved && !force) return;
    this.camera.position.copy(position);
    this.orbit.target.copy(center);
    this.camera.lookAt(center);
    this.orbit.update();
    this.lastFollowed = null;
  }

  /** Keeps the camera's offset to a moving point (a walking subject's hips). */
  follow(pointFn) {
    this.followed = pointFn;
    this.lastFollowed = null;
  }

  update() {
    if (this.followed) {
      const p = this.followed();
      if (p) {
        if (this.lastFollowed) {
          const delta = p.clone().sub(this.lastFollowed);
          this.camera.position.add(delta);
          this.orbit.target.add(delta);
        }
        this.lastFollowed = p.clone();
      }
    }
    this.orbit.update();
  }
}

/**
 * Whether WebGL runs on a CPU rasteriser (SwiftShader, llvmpipe): such a renderer spends its
 * time per pixel and per MSAA sample, so the viewer draws without antialiasing there.
 */
export function softwareRendered() {
  try {
    const gl = document.createElement('canvas').getContext('webgl2') ?? document.createElement('canvas').getContext('webgl');
    if (!gl) return true;
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    const name = String(info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER));
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return /swiftshader|llvmpipe|software|softpipe/i.test(name);
  } catch {
    return true;
  }
}

/**
 * The frame-time budget. A stream is smooth when poses reach the screen promptly at a steady
 * rate; on a slow (software) renderer two things break that. Rendering every display frame
 * leaves the page no time to read the socket, so frames queue in the browser and latency
 * grows by seconds; and each frame costs per pixel. So: (1) a render is skipped until the
 * time since the previous one is at least twice what that render took, which keeps half the
 * main thread for the stream (newest frame per subject wins, so nothing piles up); (2) when
 * renders stay slower than the budget (a 60 Hz stream wants ~30 per second at least), the
 * canvas renders at a lower pixel ratio, down to `minRatio`, and climbs back when renders are
 * quick again; (3) label placement (DOM work) is thinned while over budget.
 */
export class FrameBudget {
  constructor(renderer, { budgetMs = 33, minRatio = 0.5 } = {}) {
    this.renderer = renderer;
    this.budgetMs = budgetMs;
    this.minRatio = minRatio;
    this.maxRatio = Math.min(window.devicePixelRatio || 1, 2);
    this.ratio = this.maxRatio;
    this.intervalMs = 1000 / 60; // mean time between renders
    this.renderMs = 0; // mean time a render takes
    this.lastRender = null;
    this.renders = 0;
    this.sinceChange = 0;
    this.rendersPerSecond = 0;
    this.windowStart = performance.now();
    this.windowRenders = 0;
    this.frozen = false; // keep the resolution (a paused, inspected view)
  }

  /** Whether to render at this display frame. */
  due(now) {
    this.windowFrames = (this.windowFrames ?? 0) + 1;
    return this.lastRender === null || now - this.lastRender >= 2 * this.renderMs;
  }

  /** Call after each render with its start time and duration. */
  rendered(now, renderMs) {
    if (this.lastRender !== null) this.intervalMs = 0.9 * this.intervalMs + 0.1 * (now - this.lastRender);
    this.renderMs = this.renders === 0 ? renderMs : 0.9 * this.renderMs + 0.1 * renderMs;
    this.lastRender = now;
    this.renders++;
    this.windowRenders++;
    if (now - this.windowStart >= 1000) {
      this.rendersPerSecond = (1000 * this.windowRenders) / (now - this.windowStart);
      // Display frames the browser offered (rendered or skipped): below 60 the browser itself
      // (compositing, a CPU rasteriser in the GPU process) is the limit, not the page.
      this.displayFramesPerSecond = (1000 * this.windowFrames) / (now - this.windowStart);
      this.windowFrames = 0;
      this.windowStart = now;
      this.windowRenders = 0;
    }
    this.sinceChange++;
    if (this.sinceChange < 5 || this.frozen) return; // let a change show its effect first
    let next = this.ratio;
    if (this.intervalMs > this.budgetMs && this.ratio > this.minRatio) next = Math.max(this.minRatio, this.ratio * 0.75);
    else if (this.intervalMs < this.budgetMs * 0.5 && this.ratio < this.maxRatio) next = Math.min(this.maxRatio, this.ratio / 0.75);
    if (next !== this.ratio) {
      this.ratio = next;
      this.sinceChange = 0;
      this.renderer.setPixelRatio(next);
      const canvas = this.renderer.domElement;
      this.renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
    }
  }

  /** Labels are DOM work: place them at every render only while within budget. */
  labelsDue() {
    return this.intervalMs <= this.budgetMs || this.renders % 3 === 0;
  }

  report() {
    return {
      frameMs: this.intervalMs,
      renderMs: this.renderMs,
      rendersPerSecond: this.rendersPerSecond,
      displayFramesPerSecond: this.displayFramesPerSecond ?? 0,
      pixelRatio: this.ratio,
      budgetMs: this.budgetMs,
    };
  }
}
