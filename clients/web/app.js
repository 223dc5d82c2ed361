// rigcast viewer: every subject side by side (sources and their retargeted targets) — a
// target with a model file as its skinned mesh (GLB, VRM), everything else as a skeleton —
// with foot-plant markers, a subject list, a live rate/latency graph and the mapping table.
// Plain ES modules; three.js and three-vrm are vendored under vendor/ (no CDN at run time),
// `three` resolved by index.html's import map.
import * as THREE from 'three';
import { Stream, WANTED_PROTOCOL_VERSION } from './stream.js';
import { Graph } from './graph.js';
import { ModelView } from './model.js';
import { CameraRig, softwareRendered } from './controls.js';
import { LEVELS, QualityBudget, levelIndex } from './budget.js';

const KIND_COLORS = { source: 0x4fc3f7, target: 0xff8a65 };
const $ = (id) => document.getElementById(id);

const state = {
  hello: null,
  subjects: new Map(), // id -> info from hello
  skeletons: new Map(), // id -> skeleton message
  mappings: new Map(), // target id -> mapping message
  sourceStatus: new Map(), // source id -> newest source_status record
  targetStatus: new Map(), // target id -> its record in the newest source_status (motion, fault)
  views: new Map(), // id -> SubjectView
  latest: new Map(), // id -> newest frame not yet drawn
  stats: new Map(), // id -> { arrivals: [], latencyMs }
  framesReceived: 0,
  framesDrawn: 0,
  missed: 0,
  mappingSubject: null,
  colorMode: 'gradient',
  inPlace: true, // drop horizontal root travel so walking subjects stay in view
  footplants: new Map(), // target id -> newest footplants message
  showSkeleton: true, // the bone overlay (on top of meshes)
  showMeshes: true,
  paused: false,
  only: null, // subject picker: show only this subject (null: all)
  follow: null, // follow this subject with the camera
  modelErrors: new Map(), // id -> why its model could not be shown
};
window.rigcast = state; // for tests and the curious (devtools)

// URL parameters. `quality=full|balanced|low` fixes the frame budget's level. The others take
// one cost out at a time, to measure where a frame's time goes (BENCHMARKS.md, issue 15):
// `ratio=R` a fixed pixel ratio, `skinning=off` meshes drawn in their rest pose (no vertex
// skinning), `meshes=off` stick figures only, `labels=off`, `panel=off` (no side-panel
// refresh), `render=off` (everything but the WebGL draw).
const params = new URLSearchParams(location.search);
const probe = {
  ratio: params.has('ratio') ? Number(params.get('ratio')) : null,
  skinning: params.get('skinning') !== 'off',
  labels: params.get('labels') !== 'off',
  panel: params.get('panel') !== 'off',
  render: params.get('render') !== 'off',
};
if (params.get('meshes') === 'off') { state.showMeshes = false; $('show-meshes').checked = false; }
const forcedQuality = params.has('quality') ? levelIndex(params.get('quality')) : -1;

// -- three.js scene ------------------------------------------------------------------------
const canvas = $('scene');
// No MSAA on a CPU rasteriser: it multiplies the per-pixel cost (see controls.js).
const software = softwareRendered();
const renderer = new THREE.WebGLRenderer({ canvas, antialias: !software, preserveDrawingBuffer: true });
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x15171c);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
const grid = new THREE.GridHelper(20, 40, 0x3a4050, 0x262a35);
scene.add(grid);
// Skinned meshes need light; a hemisphere and a key light are enough for any material.
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 2.0));
const keyLight = new THREE.DirectionalLight(0xffffff, 1.5);
keyLight.position.set(2, 4, 3);
scene.add(keyLight);
const rig = new CameraRig(camera, canvas);

// -- frame-time budget (budget.js) ---------------------------------------------------------
// Something to draw besides new poses (a toggle, a layout, a model, a message): set by
// invalidate(); a display frame with no new pose, no camera move and nothing invalidated is
// not rendered (paused, or a stream slower than the display).
let needsRender = true;
function invalidate() { needsRender = true; }
const budget = new QualityBudget({ forced: forcedQuality, onChange: applyQuality });
// Where the main thread's time goes: milliseconds per second, per kind of work.
const work = { decode: 0, apply: 0, render: 0, labels: 0, panel: 0 };
let workShown = { ...work };
let workSince = performance.now();
function timed(kind, fn) {
  const t = performance.now();
  const result = fn();
  work[kind] += performance.now() - t;
  return result;
}
function applyQuality(level) {
  const dpr = window.devicePixelRatio || 1;
  renderer.setPixelRatio(probe.ratio ?? Math.min(level.pixelRatio, dpr));
  const { clientWidth: w, clientHeight: h } = canvas.parentElement;
  renderer.setSize(w, h, false);
  for (const view of state.views.values()) {
    view.model?.setDetail(level.detail, level.cull);
    view.setJointSegments(level.jointSegments);
  }
  invalidate();
}
state.perf = () => ({
  ...budget.report(),
  software,
  pixelRatio: renderer.getPixelRatio(),
  workMsPerSecond: workShown,
  renders: renderer.info.render.frame,
  renderReasons: { ...renderReasons },
  triangles: renderer.info.render.triangles,
});
state.camera = () => ({ position: camera.position.toArray(), target: rig.orbit.target.toArray(), userMoved: rig.userMoved, followed: rig.lastFollowed?.toArray() ?? null });
const labelLayer = $('labels');

function nowNanos() {
  return (performance.timeOrigin + performance.now()) * 1e6;
}

class SubjectView {
  constructor(info, skeleton) {
    this.info = info;
    this.bones = skeleton.bones;
    const n = this.bones.length;
    this.parents = this.bones.map((b) => (b.parent === null || b.parent === undefined ? -1 : b.parent));
    this.restT = this.bones.map((b) => new THREE.Vector3(...b.rest_translation));
    this.restR = this.bones.map((b) => new THREE.Quaternion(...b.rest_rotation));
    // Version 2 frames: slot k of the frame's translations belongs to the k-th marked bone.
    this.slot = new Array(n).fill(-1);
    let slots = 0;
    this.bones.forEach((b, i) => { if (b.translated) this.slot[i] = slots++; });
    this.numTranslated = slots;
    this.worldR = this.bones.map(() => new THREE.Quaternion());
    this.worldP = this.bones.map(() => new THREE.Vector3());
    this.shift = { dx: 0, dz: 0 }; // the in-place shift of the last pose
    this.localR = new THREE.Quaternion();
    this.tmp = new THREE.Vector3();
    this.group = new THREE.Group();
    this.edges = [];
    for (let i = 0; i < n; i++) if (this.parents[i] >= 0) this.edges.push([this.parents[i], i]);
    const linePositions = new Float32Array(this.edges.length * 6);
    this.lineColors = new Float32Array(this.edges.length * 6);
    this.lineGeometry = new THREE.BufferGeometry();
    this.lineGeometry.setAttribute('position', new THREE.BufferAttribute(linePositions, 3));
    this.lineGeometry.setAttribute('color', new THREE.BufferAttribute(this.lineColors, 3));
    // The overlay: lines and joints drawn over a mesh (no depth test), so both show.
    this.overlay = new THREE.Group();
    this.overlay.renderOrder = 2;
    this.lineMaterial = new THREE.LineBasicMaterial({ vertexColors: true, depthTest: false, transparent: true });
    this.overlay.add(new THREE.LineSegments(this.lineGeometry, this.lineMaterial));
    this.group.add(this.overlay);
    this.rest();
    this.restWorldP = this.worldP.map((p) => p.clone());
    this.floorY = Math.min(...this.restWorldP.map((p) => p.y));
    this.model = null;
    this.lost = false;
    this.markers = new Map(); // foot bone -> marker mesh
    // In place: the deepest translated bone of the root chain (the hips of most rigs) keeps
    // its rest ground position; everything moves with it. The chain goes down while one
    // translated child carries bones of its own: a translated leaf beside it (an IK foot under
    // the armature root) is no part of it, and the body ends it where it branches.
    const kids = this.bones.map(() => []);
    this.parents.forEach((p, i) => { if (p >= 0) kids[p].push(i); });
    this.anchor = 0;
    for (;;) {
      const next = kids[this.anchor].filter((c) => this.slot[c] >= 0 && kids[c].length > 0);
      if (next.length !== 1) break;
      this.anchor = next[0];
    }
    this.height = this.computeHeight();
    this.jointRadius = Math.max(this.height * 0.012, 0.004);
    this.jointSegments = budget.current.jointSegments;
    this.joints = new THREE.InstancedMesh(this.jointGeometry(), new THREE.MeshBasicMaterial({ depthTest: false, transparent: true }), n);
    this.joints.renderOrder = 2;
    this.overlay.add(this.joints);
    this.matrix = new THREE.Matrix4();
    this.setColors(null);
    // Labels: the subject's name, and the bone names at the tips of chains (hands, feet, head).
    const from = info.kind === 'target' ? ` ← ${state.subjects.get(info.source)?.name ?? info.source}` : '';
    this.labelText = `${info.name} (${info.kind}${from})`;
    this.subjectLabel = makeLabel(this.labelText, `subject ${info.kind}`);
    this.boneLabels = [];
    for (let i = 0; i < n; i++) {
      if (kids[i].length === 0 || this.parents[i] < 0) this.boneLabels.push([i, makeLabel(this.bones[i].name, 'bone')]);
    }
    this.update();
  }

  rest() {
    this.fk(null);
  }

  /** A joint's sphere at the budget level's tessellation: hundreds of joints on screen make
   *  them a large share of a software rasteriser's triangles. */
  jointGeometry() {
    const [w, h] = this.jointSegments;
    return new THREE.SphereGeometry(this.jointRadius, w, h);
  }

  setJointSegments(segments) {
    if (segments.join() === this.jointSegments.join()) return;
    this.jointSegments = segments;
    this.joints.geometry.dispose();
    this.joints.geometry = this.jointGeometry();
  }

  computeHeight() {
    let min = Infinity, max = -Infinity;
    for (const p of this.worldP) { min = Math.min(min, p.y); max = Math.max(max, p.y); }
    return Math.max(max - min, 0.1);
  }

  bounds() {
    const box = new THREE.Box3();
    for (const p of this.worldP) box.expandByPoint(p);
    return box;
  }

  fk(frame) {
    const n = this.bones.length;
    // Which frame the drawn pose is (null at rest): lets a footplants message be matched to it.
    this.drawnSeq = frame ? frame.seq : null;
    for (let i = 0; i < n; i++) {
      const r = this.localR;
      if (frame) r.set(frame.rotations[4 * i], frame.rotations[4 * i + 1], frame.rotations[4 * i + 2], frame.rotations[4 * i + 3]);
      else r.copy(this.restR[i]);
      const p = this.parents[i];
      const t = this.tmp.copy(this.restT[i]);
      if (frame && frame.version === 2 && this.slot[i] >= 0 && frame.translations.length === 3 * this.numTranslated) {
        const k = 3 * this.slot[i];
        t.set(frame.translations[k], frame.translations[k + 1], frame.translations[k + 2]);
      } else if (frame && frame.version !== 2 && i === 0) {
        t.set(...frame.root);
        if (state.inPlace) { t.x = this.restT[0].x; t.z = this.restT[0].z; }
      }
      if (p < 0) {
        this.worldR[i].copy(r);
        this.worldP[i].copy(t);
      } else {
        this.worldR[i].multiplyQuaternions(this.worldR[p], r);
        this.worldP[i].copy(t.applyQuaternion(this.worldR[p])).add(this.worldP[p]);
      }
    }
    this.shift.dx = 0;
    this.shift.dz = 0;
    if (frame && frame.version === 2 && state.inPlace) {
      const dx = this.worldP[this.anchor].x - this.restWorldP[this.anchor].x;
      const dz = this.worldP[this.anchor].z - this.restWorldP[this.anchor].z;
      for (const q of this.worldP) { q.x -= dx; q.z -= dz; }
      this.shift.dx = dx;
      this.shift.dz = dz;
    }
  }

  /** The character's own mesh, loaded after the view was made; the skeleton stays as an
   *  overlay (toggle) and a fallback. */
  attachModel(model) {
    this.model = model;
    this.group.add(model.root);
    model.root.visible = state.showMeshes;
    model.drive(this.worldR, this.worldP, 0);
    this.applyVisibility();
  }

  applyVisibility() {
    // Without a mesh the skeleton is the subject: never hide it then.
    this.overlay.visible = state.showSkeleton || !this.model || !state.showMeshes;
    if (this.model) this.model.root.visible = state.showMeshes;
  }

  /** A marker on the floor under each planted foot. It sits under the foot as drawn: the
   *  message's position is where the foot stood on the message's frame (re-sent when a planted
   *  foot moves: the lock eases it onto its pin over ~0.1 s and turns it with the performer
   *  about its ball), and frames are drawn ahead of it; the message position is the fallback. */
  setFootplants(message) {
    const seen = new Set();
    for (const foot of message.feet ?? []) {
      seen.add(foot.bone);
      let marker = this.markers.get(foot.bone);
      if (!marker) {
        const r = Math.max(this.height * 0.05, 0.02);
        marker = new THREE.Mesh(
          new THREE.RingGeometry(r * 0.55, r, 24).rotateX(-Math.PI / 2),
          new THREE.MeshBasicMaterial({ color: 0x7cff6b, side: THREE.DoubleSide, depthTest: false, transparent: true, opacity: 0.9 }),
        );
        marker.renderOrder = 3;
        marker.name = `footplant ${foot.bone}`;
        this.group.add(marker);
        this.markers.set(foot.bone, marker);
      }
      marker.userData.foot = foot;
      marker.userData.seq = message.seq;
      // Before the first live pose the skeleton stands at rest, wherever that is: no marker.
      marker.visible = foot.planted === true && this.placedLive === true;
    }
    for (const [bone, marker] of this.markers) if (!seen.has(bone)) marker.visible = false;
    this.placeMarkers();
  }

  placeMarkers() {
    for (const marker of this.markers.values()) {
      const p = marker.userData.foot?.position;
      if (!p) continue;
      marker.visible = marker.userData.foot.planted === true && this.placedLive === true;
      const i = marker.userData.index ?? (marker.userData.index = this.bones.findIndex((b) => b.name === marker.userData.foot.bone));
      if (i >= 0 && this.placedLive) marker.position.set(this.worldP[i].x, this.floorY + 0.002, this.worldP[i].z);
      else marker.position.set(p[0] - this.shift.dx, this.floorY + 0.002, p[2] - this.shift.dz);
    }
  }

  /** A subject that does not follow its performer says why on its label and greys its bones:
   *  its source is lost (a target eases to rest, or walks its idle graph: `motion` from
   *  `source_status.targets`), its source failed (stopped on an internal error), or its own
   *  processing faulted (`fault` of `source_status.targets`, the server retries it). */
  setHealth(health, motion, fault) {
    const lost = health === 'lost';
    const idle = lost && motion === 'idle_graph';
    const why = fault ? `faulted: ${shortText(fault)}`
      : health === 'failed' ? 'source failed'
        : idle ? 'source lost, on idle graph' : lost ? 'source lost' : '';
    if (why === (this.why ?? '')) return;
    invalidate();
    this.why = why;
    this.lost = lost;
    this.idling = idle;
    this.failed = health === 'failed';
    this.faulted = Boolean(fault);
    const dim = why !== '';
    this.subjectLabel.classList.toggle('lost', dim);
    this.subjectLabel.title = fault ?? '';
    this.subjectLabel.textContent = this.labelText + (dim ? ` — ${why}` : '');
    this.lineMaterial.opacity = dim ? 0.35 : 1;
    this.joints.material.opacity = dim ? 0.35 : 1;
  }

  update() {
    const positions = this.lineGeometry.attributes.position.array;
    this.edges.forEach(([a, b], e) => {
      positions.set([this.worldP[a].x, this.worldP[a].y, this.worldP[a].z, this.worldP[b].x, this.worldP[b].y, this.worldP[b].z], e * 6);
    });
    this.lineGeometry.attributes.position.needsUpdate = true;
    this.lineGeometry.computeBoundingSphere();
    for (let i = 0; i < this.bones.length; i++) {
      this.matrix.makeTranslation(this.worldP[i].x, this.worldP[i].y, this.worldP[i].z);
      this.joints.setMatrixAt(i, this.matrix);
    }
    this.joints.instanceMatrix.needsUpdate = true;
    this.joints.computeBoundingSphere();
  }

  /** colors: Map bone name -> [r, g, b] (0..1), or null for the subject's kind colour. */
  setColors(colors) {
    const base = new THREE.Color(KIND_COLORS[this.info.kind] ?? 0xcccccc);
    const color = new THREE.Color();
    const boneColor = (i) => {
      const c = colors?.get(this.bones[i].name);
      return c ? color.setRGB(c[0], c[1], c[2]) : color.copy(base);
    };
    // A segment parent→child is the parent bone's extent (as Blender draws bones head→tail),
    // so it wears the parent's colour: a helper root under the hips stays grey.
    this.edges.forEach(([a], e) => {
      boneColor(a);
      this.lineColors.set([color.r, color.g, color.b, color.r, color.g, color.b], e * 6);
    });
    this.lineGeometry.attributes.color.needsUpdate = true;
    for (let i = 0; i < this.bones.length; i++) this.joints.setColorAt(i, boneColor(i));
    if (this.joints.instanceColor) this.joints.instanceColor.needsUpdate = true;
  }

  placeLabels(width, height, placed) {
    const v = new THREE.Vector3();
    const place = (label, point, lift) => {
      v.copy(point).add(this.group.position);
      v.y += lift;
      v.project(camera);
      const x = ((v.x + 1) / 2) * width;
      const y = ((1 - v.y) / 2) * height;
      // Skip a label that would overprint one already placed this frame (readability); labels
      // are centred on x, so two overlap when their centres are closer than half their widths.
      // Measured once per text (a layout read each frame would cost more than the labels).
      if (label.measuredText !== label.textContent) {
        label.style.display = 'block';
        label.measuredWidth = label.offsetWidth || label.textContent.length * 6.5 + 8;
        label.measuredText = label.textContent;
      }
      const labelWidth = label.measuredWidth;
      const crowded = placed.some(([px, py, pw]) => Math.abs(px - x) < (pw + labelWidth) / 2 && Math.abs(py - y) < 13);
      const visible = v.z < 1 && Math.abs(v.x) <= 1.1 && Math.abs(v.y) <= 1.1 && !crowded;
      label.style.display = visible ? 'block' : 'none';
      if (!visible) return;
      placed.push([x, y, labelWidth]);
      label.style.left = `${x}px`;
      label.style.top = `${y}px`;
    };
    if (!this.group.visible) {
      this.subjectLabel.style.display = 'none';
      for (const [, label] of this.boneLabels) label.style.display = 'none';
      return;
    }
    let top = this.worldP[0];
    for (const p of this.worldP) if (p.y > top.y) top = p;
    place(this.subjectLabel, new THREE.Vector3(this.worldP[0].x, top.y, this.worldP[0].z), this.height * 0.1);
    for (const [i, label] of this.boneLabels) place(label, this.worldP[i], this.height * 0.02);
  }

  dispose() {
    this.disposed = true;
    // A rebuilt view loads its model again: free this one's GPU buffers and textures.
    this.model?.root.traverse((object) => {
      object.geometry?.dispose();
      for (const material of [object.material ?? []].flat()) {
        for (const value of Object.values(material)) if (value?.isTexture) value.dispose();
        material.dispose?.();
      }
    });
    this.subjectLabel.remove();
    for (const [, label] of this.boneLabels) label.remove();
    scene.remove(this.group);
  }
}

/** What the tests read about meshes: per subject with a model, its skinned meshes and a
 *  sample of the first one's bone matrices (they change as the pose does). */
state.meshes = () => {
  const out = {};
  for (const [id, view] of state.views) {
    if (!view.model) continue;
    out[id] = {
      skinnedMeshes: view.model.skinnedMeshes.length,
      drawnSkinned: view.model.drawnMeshes().length,
      drawnVertices: view.model.drawnMeshes().reduce((s, m) => s + m.geometry.attributes.position.count, 0),
      fileVertices: view.model.verticesFull,
      detail: view.model.detail,
      proxyMs: view.model.proxyMs,
      isVrm: view.model.vrm !== null,
      bound: view.model.numBound,
      bones: view.bones.length,
      visible: view.model.root.visible,
      boneMatrices: view.model.boneMatrixSample(),
    };
  }
  return out;
};

/** The foot-plant markers: per subject, per foot, shown or not, and where (scene space). */
state.footMarkers = () => {
  const out = {};
  for (const [id, view] of state.views) {
    out[id] = [...view.markers].map(([bone, m]) => {
      const p = m.getWorldPosition(new THREE.Vector3());
      const i = view.bones.findIndex((b) => b.name === bone);
      const j = i >= 0 ? view.worldP[i].clone().add(view.group.position) : null;
      const f = m.userData.foot?.position;
      const message = f && [f[0] - view.shift.dx + view.group.position.x, f[1], f[2] - view.shift.dz + view.group.position.z];
      return {
        bone, visible: m.visible, planted: m.userData.foot?.planted === true, live: view.placedLive === true, message,
        messageSeq: m.userData.seq ?? null, drawnSeq: view.drawnSeq ?? null,
        position: [p.x, p.y, p.z], joint: j && [j.x, j.y, j.z], floor: view.floorY + view.group.position.y,
      };
    });
  }
  return out;
};

/** Screen-space box [left, top, right, bottom] (CSS px) of each subject's joints, by id. */
state.screenBounds = () => {
  const { clientWidth: w, clientHeight: h } = canvas.parentElement;
  const v = new THREE.Vector3();
  const out = {};
  for (const [id, view] of state.views) {
    const box = [Infinity, Infinity, -Infinity, -Infinity];
    for (const p of view.worldP) {
      v.copy(p).add(view.group.position).project(camera);
      const x = ((v.x + 1) / 2) * w;
      const y = ((1 - v.y) / 2) * h;
      box[0] = Math.min(box[0], x); box[1] = Math.min(box[1], y);
      box[2] = Math.max(box[2], x); box[3] = Math.max(box[3], y);
    }
    out[id] = box;
  }
  return out;
};

/** At most the first 80 characters of a server's text (a fault's reason) for a label. */
function shortText(text) {
  const t = String(text);
  return t.length > 80 ? `${t.slice(0, 80)}…` : t;
}

function makeLabel(text, kind) {
  const div = document.createElement('div');
  div.className = `label ${kind}`;
  div.textContent = text;
  labelLayer.appendChild(div);
  return div;
}

// Sources first, each followed by its retargeted targets, side by side along +X.
function layout(forceCamera = false) {
  const order = [];
  // The subject picker shows one subject alone (and frames it).
  for (const [id, view] of state.views) view.group.visible = state.only === null || state.only === id;
  const ids = [...state.views.keys()].filter((id) => state.views.get(id).group.visible).sort((a, b) => a - b);
  for (const id of ids) {
    const view = state.views.get(id);
    if (view.info.kind !== 'target' || !state.views.has(view.info.source)) {
      order.push(view);
      for (const other of ids) {
        const o = state.views.get(other);
        if (o.info.kind === 'target' && o.info.source === id) order.push(o);
      }
    }
  }
  let x = 0;
  const all = new THREE.Box3();
  for (const view of order) {
    const box = view.bounds();
    const width = Math.max(box.max.x - box.min.x, view.height * 0.6);
    const gap = view.height * 0.35;
    view.group.position.set(x + width / 2 - (box.min.x + box.max.x) / 2, 0, -(box.min.z + box.max.z) / 2);
    if (!view.group.parent) scene.add(view.group);
    x += width + gap;
    all.union(box.clone().translate(view.group.position));
  }
  if (order.length === 0) return;
  const center = all.getCenter(new THREE.Vector3());
  const size = all.getSize(new THREE.Vector3());
  const fit = Math.max(size.y * 1.7, (size.x * 1.15) / Math.max(camera.aspect, 0.1));
  const distance = fit / (2 * Math.tan(THREE.MathUtils.degToRad(camera.fov / 2)));
  rig.frame(new THREE.Vector3(center.x, center.y + size.y * 0.25, center.z + distance), center, forceCamera);
  grid.position.set(center.x, all.min.y, center.z);
  grid.scale.setScalar(Math.max(size.x, size.y) / 10);
}

function resize() {
  const { clientWidth: w, clientHeight: h } = canvas.parentElement;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  layout();
  invalidate();
}
window.addEventListener('resize', resize);

// -- stream handling -----------------------------------------------------------------------
function rebuildView(id) {
  const info = state.subjects.get(id);
  const skeleton = state.skeletons.get(id);
  state.views.get(id)?.dispose();
  state.views.delete(id);
  if (!info || !skeleton) return;
  const view = new SubjectView(info, skeleton);
  state.views.set(id, view);
  if (info.model) loadModel(id, view, skeleton);
  resize();
  applyMappingColors();
  renderSubjects();
}

/** Fetches a target's model (only offered for targets whose file the server serves). */
function loadModel(id, view, skeleton) {
  const url = `/v1/subjects/${id}/model.glb${streamQuery}`;
  const details = LEVELS.map((l) => l.detail);
  ModelView.load(url, skeleton.bones, { cheap: software, details }).then((model) => {
    if (view.disposed) return; // a newer skeleton replaced this view meanwhile
    if (model.numBound === 0) throw new Error('no node of the model matches a bone of the skeleton');
    model.setDetail(budget.current.detail, budget.current.cull);
    if (!probe.skinning) for (const mesh of model.root.getObjectsByProperty('isSkinnedMesh', true)) mesh.isSkinnedMesh = false;
    view.attachModel(model);
    invalidate();
    state.modelErrors.delete(id);
    layout();
  }).catch((error) => {
    // Keep the stick figure and say why.
    state.modelErrors.set(id, String(error?.message ?? error));
    console.warn(`subject ${id}: model not shown: ${error}`);
    renderSubjects();
  });
}

function setSubjects(list) {
  state.subjects = new Map(list.map((s) => [s.id, s]));
  renderPickers();
  for (const id of [...state.views.keys()]) if (!state.subjects.has(id)) { state.views.get(id).dispose(); state.views.delete(id); }
  if (state.mappingSubject === null || !state.subjects.has(state.mappingSubject)) {
    state.mappingSubject = list.find((s) => s.kind === 'target')?.id ?? null;
  }
  renderSubjects();
}

function onMessage(message) {
  // Messages that change the picture (skeletons, subjects, colours, markers, a lost source)
  // invalidate it; the rest (status once a second, acks) leave a still view undrawn.
  if (['hello', 'subjects_changed', 'skeleton', 'mapping'].includes(message.type)) invalidate();
  if (message.type === 'footplants' && !state.paused) invalidate();
  switch (message.type) {
    case 'hello':
      state.hello = message;
      // Ask for version 2 frames (the hips' own motion, not only bone 0's) when offered.
      if ((message.protocol_versions ?? [1]).includes(WANTED_PROTOCOL_VERSION)) {
        state.stream?.send({ type: 'set_protocol', version: WANTED_PROTOCOL_VERSION });
      }
      $('server-version').textContent = `server ${message.server_version ?? '?'} · protocol ${message.protocol_version} · tick ${message.tick_hz} Hz`;
      setSubjects(message.subjects ?? []);
      break;
    case 'subjects_changed':
      setSubjects(message.subjects ?? []);
      break;
    case 'skeleton':
      state.skeletons.set(message.subject, message);
      rebuildView(message.subject);
      break;
    case 'protocol':
      state.protocolVersion = message.version;
      $('server-version').textContent = `server ${state.hello?.server_version ?? '?'} · protocol ${message.version} · tick ${state.hello?.tick_hz} Hz`;
      break;
    case 'mapping':
      state.mappings.set(message.subject, message);
      renderMapping();
      applyMappingColors();
      break;
    case 'source_status':
      for (const record of message.sources ?? []) state.sourceStatus.set(record.subject, record);
      state.targetStatus = new Map((message.targets ?? []).map((t) => [t.subject, t]));
      for (const view of state.views.values()) {
        const health = state.sourceStatus.get(view.info.kind === 'target' ? view.info.source : view.info.id);
        const target = (message.targets ?? []).find((t) => t.subject === view.info.id);
        view.setHealth(health?.state, target?.motion, target?.fault);
      }
      renderSubjects();
      break;
    case 'footplants':
      state.footplants.set(message.subject, message);
      state.views.get(message.subject)?.setFootplants(message);
      break;
    case 'lagged':
      state.missed += message.missed ?? 0;
      break;
    default:
      break;
  }
}

function onFrame(frame) {
  state.framesReceived++;
  state.missed += frame.missedFrames;
  state.latest.set(frame.subject, frame);
  let stats = state.stats.get(frame.subject);
  if (!stats) { stats = { arrivals: [], latencyMs: 0, count: 0 }; state.stats.set(frame.subject, stats); }
  stats.count++;
  const now = performance.now();
  stats.arrivals.push(now);
  stats.latencyMs = (nowNanos() - Number(frame.captureNanos)) / 1e6;
}

// A page opened with ?token=… (the link `rigcast serve` and `rigcast token show` print) hands
// the control token on to the stream: needed to change the server, and to stream at all from
// a server listening beyond loopback.
const pageToken = new URLSearchParams(location.search).get('token');
const streamQuery = pageToken ? `?token=${encodeURIComponent(pageToken)}` : '';
const stream = new Stream(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/v1/stream${streamQuery}`, {
  onOpen: () => { $('connection').textContent = 'connected'; $('connection').className = 'ok'; },
  onClose: () => { $('connection').textContent = 'disconnected — reconnecting'; $('connection').className = 'bad'; },
  onMessage,
  onFrame,
});
state.stream = stream;

// -- side panel ----------------------------------------------------------------------------
function renderSubjects() {
  const list = $('subjects');
  list.replaceChildren();
  for (const info of state.subjects.values()) {
    const li = document.createElement('li');
    li.style.borderColor = `#${(KIND_COLORS[info.kind] ?? 0xcccccc).toString(16).padStart(6, '0')}`;
    const source = info.kind === 'target' ? ` ← ${state.subjects.get(info.source)?.name ?? info.source}` : '';
    const stats = state.stats.get(info.id);
    const rate = stats ? `${rateOf(stats).toFixed(0)} fps · ${stats.latencyMs.toFixed(1)} ms` : 'no frames yet';
    li.innerHTML = `<b></b>${source} <small>${info.kind}, ${info.num_bones} bones, ${rate}</small><div class="health"></div>`;
    li.querySelector('b').textContent = `${info.id} ${info.name}`;
    li.dataset.subject = String(info.id);
    // Health of the input: the source's own, or for a target the source driving it.
    const health = state.sourceStatus.get(info.kind === 'target' ? info.source : info.id);
    const healthDiv = li.querySelector('.health');
    if (health) {
      li.dataset.health = health.state;
      const badge = document.createElement('span');
      badge.className = `state ${health.state}`;
      badge.textContent = health.state;
      healthDiv.append(badge, info.kind === 'target'
        ? ` source ${state.subjects.get(info.source)?.name ?? info.source}`
        : ` ${health.kind} · in ${Number(health.input_fps ?? 0).toFixed(0)} fps · ${Number(health.latency_ms ?? 0).toFixed(1)} ms · dropped ${health.dropped ?? 0}`);
    } else {
      healthDiv.textContent = 'no source status yet';
    }
    const fault = state.targetStatus.get(info.id)?.fault;
    if (fault) {
      const badge = document.createElement('div');
      badge.className = 'state faulted';
      badge.textContent = `faulted: ${shortText(fault)}`;
      badge.title = fault;
      healthDiv.append(badge);
    }
    const modelError = state.modelErrors.get(info.id);
    if (info.model) {
      const note = document.createElement('div');
      note.className = modelError ? 'model bad' : 'model';
      note.textContent = modelError ? `${info.model} model not shown: ${modelError}` : `${info.model} model`;
      li.appendChild(note);
    }
    li.onclick = () => { if (info.kind === 'target') { state.mappingSubject = info.id; renderMapping(); applyMappingColors(); } };
    list.appendChild(li);
  }
}

function mappingColor(entry) {
  return state.colorMode === 'random' ? entry.color_random : entry.color_gradient;
}

function renderMapping() {
  const mapping = state.mappings.get(state.mappingSubject);
  const body = $('mapping').querySelector('tbody');
  body.replaceChildren();
  if (!mapping) { $('mapping-title').textContent = 'no retargeted subject'; $('mapping-flags').textContent = ''; return; }
  const target = state.subjects.get(mapping.subject)?.name ?? mapping.subject;
  const source = state.subjects.get(mapping.source_subject)?.name ?? mapping.source_subject;
  $('mapping-title').textContent = `${target} ← ${source}`;
  for (const entry of mapping.entries ?? []) {
    const tr = document.createElement('tr');
    if (!entry.source) tr.classList.add('unmapped');
    tr.dataset.target = entry.target;
    const c = mappingColor(entry) ?? [0.5, 0.5, 0.5];
    tr.innerHTML = '<td class="swatch"><span></span></td><td></td><td></td><td></td><td class="check"></td>';
    tr.children[0].firstChild.style.background = `rgb(${c.map((v) => Math.round(v * 255)).join(',')})`;
    tr.children[1].textContent = entry.target;
    tr.children[2].textContent = entry.source ?? '—';
    // Confidence (absent from older servers: the score).
    const sure = typeof entry.confidence === 'number' ? entry.confidence : entry.score;
    tr.children[3].textContent = typeof sure === 'number' ? sure.toFixed(2) : '';
    if (entry.flagged) {
      // A bone the mapper is unsure of: marked, with why, for the user to check and fix
      // with an override (set_mapping, a mapping file, or the Blender add-on's list).
      tr.classList.add('flagged');
      tr.children[4].textContent = '⚠';
      tr.title = `check this bone: ${entry.flagged}`;
    }
    body.appendChild(tr);
  }
  const flagged = (mapping.entries ?? []).filter((entry) => entry.flagged).length;
  $('mapping-flags').textContent = flagged
    ? `${flagged} bone${flagged === 1 ? '' : 's'} to check (⚠, reason on hover); fix with overrides`
    : 'no bones flagged';
}

function applyMappingColors() {
  for (const view of state.views.values()) view.setColors(null);
  for (const mapping of state.mappings.values()) {
    const targetColors = new Map();
    const sourceColors = new Map();
    for (const entry of mapping.entries ?? []) {
      const c = mappingColor(entry);
      if (!c) continue;
      targetColors.set(entry.target, c);
      if (entry.source) sourceColors.set(entry.source, c);
    }
    state.views.get(mapping.subject)?.setColors(targetColors);
    if (mapping.subject === state.mappingSubject) state.views.get(mapping.source_subject)?.setColors(sourceColors);
  }
}

$('in-place').onchange = (event) => { state.inPlace = event.target.checked; };
$('show-skeleton').onchange = (event) => {
  state.showSkeleton = event.target.checked;
  for (const view of state.views.values()) view.applyVisibility();
};
$('show-meshes').onchange = (event) => {
  state.showMeshes = event.target.checked;
  for (const view of state.views.values()) view.applyVisibility();
};
$('pause').onclick = () => {
  state.paused = !state.paused;
  budget.hold(state.paused);
  $('pause').textContent = state.paused ? 'resume' : 'pause';
  $('pause').classList.toggle('on', state.paused);
};
$('reset-view').onclick = () => { rig.userMoved = false; layout(true); };
$('show-subject').onchange = (event) => {
  state.only = event.target.value === '' ? null : Number(event.target.value);
  layout(true);
};
$('follow').onchange = (event) => {
  state.follow = event.target.value === '' ? null : Number(event.target.value);
  rig.follow(state.follow === null ? null : () => {
    const view = state.views.get(state.follow);
    return view ? view.worldP[view.anchor].clone().add(view.group.position) : null;
  });
};

/** The subject picker and follow menus list the current subjects. */
function renderPickers() {
  for (const [id, first] of [['show-subject', 'all subjects'], ['follow', 'no follow']]) {
    const select = $(id);
    const value = select.value;
    select.replaceChildren(new Option(first, ''));
    for (const info of state.subjects.values()) select.add(new Option(`${info.id} ${info.name}`, String(info.id)));
    select.value = [...select.options].some((o) => o.value === value) ? value : '';
  }
}

$('color-mode').onchange = (event) => {
  state.colorMode = event.target.value;
  renderMapping();
  applyMappingColors();
};

function rateOf(stats) {
  const now = performance.now();
  while (stats.arrivals.length && now - stats.arrivals[0] > 1000) stats.arrivals.shift();
  return stats.arrivals.length;
}

// Header and panel changes (toggles, pickers, buttons) are drawn at the next display frame.
// Capture phase: a `change` dispatched without bubbling still passes the document.
for (const type of ['change', 'click', 'input']) document.addEventListener(type, invalidate, true);
rig.orbit.addEventListener('change', invalidate);

const graph = new Graph($('graph'));
setInterval(() => {
  const now = performance.now();
  if (probe.panel) {
    timed('panel', () => {
      const t = now / 1000;
      let rate = 0, latency = 0, n = 0;
      for (const stats of state.stats.values()) { rate = Math.max(rate, rateOf(stats)); latency += stats.latencyMs; n++; }
      if (n) graph.push(t, rate, latency / n);
      graph.draw(t);
      renderSubjects();
    });
  }
  showQuality(now);
  showFrameCount();
}, 250);

/** The status line's quality entry: level, how it was chosen, the measured rate. */
function showQuality(now) {
  if (now - workSince >= 1000) {
    work.decode = stream.decodeMs - (showQuality.decoded ?? 0);
    showQuality.decoded = stream.decodeMs;
    workShown = Object.fromEntries(Object.entries(work).map(([k, v]) => [k, (1000 * v) / (now - workSince)]));
    for (const k of Object.keys(work)) work[k] = 0;
    workSince = now;
  }
  const report = budget.report();
  const el = $('quality');
  el.dataset.quality = report.quality;
  el.dataset.forced = String(report.forced);
  const rate = state.paused ? 'paused' : `${report.rendersPerSecond.toFixed(0)} fps`;
  el.textContent = `quality ${report.quality} (${report.forced ? 'forced' : 'auto'}) · ${rate}`;
  el.title = `frame budget ${report.budgetMs} ms; mean frame ${report.frameMs.toFixed(0)} ms; pixel ratio ${renderer.getPixelRatio()}`;
}

/** The camera moved since the last render (orbit events miss layout and follow moves). Not
 *  exact equality: OrbitControls.update() recomputes the position from its spherical angles
 *  every frame, which can wander by a rounding error and would re-render a still view. */
const lastCamera = new THREE.Matrix4();
function cameraMoved() {
  camera.updateMatrixWorld();
  const a = camera.matrixWorld.elements, b = lastCamera.elements;
  return a.some((v, i) => Math.abs(v - b[i]) > 1e-6 * Math.max(1, Math.abs(b[i])));
}

// -- draw loop: newest frame per subject, at most once per display frame -------------------
let lastDraw = performance.now();
let renderCount = 0;
const renderReasons = { pose: 0, invalidated: 0, camera: 0 };
function draw() {
  const start = performance.now();
  requestAnimationFrame(draw);
  budget.frame(start);
  const fresh = !state.paused && state.latest.size > 0;
  rig.update();
  const moved = cameraMoved();
  if (!fresh && !needsRender && !moved) return; // nothing new to show
  if (!budget.due(start)) return; // leave the main thread to the stream (see budget.js)
  // Why each render happened (tests and devtools: a still view should not render).
  renderReasons[fresh ? 'pose' : needsRender ? 'invalidated' : 'camera']++;
  const dt = Math.min((start - lastDraw) / 1000, 0.1);
  lastDraw = start;
  needsRender = false;
  if (fresh) timed('apply', applyLatest.bind(null, dt));
  const { clientWidth: w, clientHeight: h } = canvas.parentElement;
  if (probe.render) timed('render', () => renderer.render(scene, camera));
  lastCamera.copy(camera.matrixWorld);
  if (probe.labels && renderCount++ % budget.current.labelEvery === 0) {
    timed('labels', () => {
      const placed = [];
      for (const view of state.views.values()) view.placeLabels(w, h, placed);
    });
  }
  showFrameCount();
  budget.rendered(start, performance.now() - start);
}

/** Frames received, in the header and the title (also while nothing is rendered). */
function showFrameCount() {
  const counter = $('frame-count');
  counter.textContent = String(state.framesReceived);
  counter.dataset.frames = String(state.framesReceived);
  document.title = `rigcast viewer — ${state.framesReceived} frames`;
}

/** The newest frame of each subject onto its view (older ones were dropped on arrival). */
function applyLatest(dt) {
  for (const [id, frame] of state.latest) {
    const view = state.views.get(id);
    if (view && frame.numBones === view.bones.length) {
      view.fk(frame);
      view.update();
      if (view.model && state.showMeshes) view.model.drive(view.worldR, view.worldP, dt);
      state.framesDrawn++;
      // Rest poses can sit anywhere (BVH roots at the origin, feet below the floor): lay the
      // views out again on each subject's first live pose.
      if (!view.placedLive) {
        view.placedLive = true;
        view.height = view.computeHeight();
        layout();
      }
      // After the first live pose is marked as such: a foot already planted shows its marker
      // from this frame, not the next one.
      view.placeMarkers();
    }
  }
  state.latest.clear();
}
applyQuality(budget.current);
resize();
requestAnimationFrame(draw);
