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
 * Watches how long display frames take and trades resolution for rate: when the mean frame
 * interval stays above the budget (a 60 Hz stream wants a frame at least every ~33 ms to look
 * smooth), the canvas renders at a lower pixel ratio, down to `minRatio`; when frames are
 * quick again the ratio climbs back. Software rasterisers (no GPU) spend their time per pixel,
 * so this is the lever that works there; label placement is thinned too.
 */
export class FrameBudget {
  constructor(renderer, { budgetMs = 33, minRatio = 0.5 } = {}) {
    this.renderer = renderer;
    this.budgetMs = budgetMs;
    this.minRatio = minRatio;
    this.maxRatio = Math.min(window.devicePixelRatio || 1, 2);
    this.ratio = this.maxRatio;
    this.meanMs = 1000 / 60;
    this.renderMs = 0;
    this.last = null;
    this.frames = 0;
    this.sinceChange = 0;
  }

  /** Call once per display frame with the time spent drawing it. */
  tick(now, renderMs) {
    if (this.last !== null) this.meanMs = 0.9 * this.meanMs + 0.1 * (now - this.last);
    this.renderMs = 0.9 * this.renderMs + 0.1 * renderMs;
    this.last = now;
    this.frames++;
    this.sinceChange++;
    if (this.sinceChange < 30) return; // let a change show its effect first
    let next = this.ratio;
    if (this.meanMs > this.budgetMs && this.ratio > this.minRatio) next = Math.max(this.minRatio, this.ratio * 0.75);
    else if (this.meanMs < this.budgetMs * 0.6 && this.ratio < this.maxRatio) next = Math.min(this.maxRatio, this.ratio / 0.75);
    if (next !== this.ratio) {
      this.ratio = next;
      this.sinceChange = 0;
      this.renderer.setPixelRatio(next);
      const canvas = this.renderer.domElement;
      this.renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
    }
  }

  /** Labels are DOM work: place them every frame only while within budget. */
  labelsDue() {
    return this.meanMs <= this.budgetMs || this.frames % 4 === 0;
  }

  report() {
    return { frameMs: this.meanMs, renderMs: this.renderMs, pixelRatio: this.ratio, budgetMs: this.budgetMs };
  }
}

