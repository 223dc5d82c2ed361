// Camera: orbit/zoom (three.js OrbitControls) and following a subject; and whether WebGL
// renders in software (the frame-time budget itself is budget.js).
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
