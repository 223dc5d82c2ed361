// A target character's own model (GLB, or VRM through three-vrm), posed from the stream.
//
// The server's skeleton for a glTF target is the file's skin joints (plus the nodes between
// them), named after their nodes, with every ancestor scale baked into translations and the
// transform of the nodes above the top joints folded into the top bones, so its forward
// kinematics gives the joints' true positions in the file's space. The model is therefore
// driven through world transforms, not by copying local rotations: each joint node gets the
// model-space transform the viewer's FK computed for its bone (keeping the node's own rest
// scale), written back as the local transform relative to its parent. Whatever the file's
// armature scale or axis conversion, the mesh follows exactly the skeleton the viewer draws.
import * as THREE from 'three';
import { GLTFLoader } from './vendor/three/addons/loaders/GLTFLoader.js';
import { VRMLoaderPlugin } from './vendor/three-vrm/three-vrm.module.min.js';
import { clusterMeshes, decimatable } from './decimate.js';

const loader = new GLTFLoader();
// Adds `userData.vrm` to VRM files (VRM 0.x and 1.0); plain GLBs load as before.
loader.register((parser) => new VRMLoaderPlugin(parser));

/** The server's name for glTF node `index` (sources/src/gltf/read.rs `unique_names`). */
function serverNames(json) {
  return (json.nodes ?? []).map((node, index) => (node.name ? node.name : `joint_${index}`));
}

export class ModelView {
  /** Loads `url`; `bones` is the subject's skeleton message `bones`. Rejects on a bad file. */
  static async load(url, bones, { cheap = false, details = [] } = {}) {
    const gltf = await loader.loadAsync(url);
    const view = new ModelView(gltf, bones, cheap);
    view.makeProxies(details);
    return view;
  }

  /** `cheap`: replace physically based materials by Lambert ones (same colour and texture),
   *  several times cheaper per pixel on a CPU rasteriser; VRM's MToon stays. */
  constructor(gltf, bones, cheap = false) {
    this.vrm = gltf.userData.vrm ?? null;
    this.root = this.vrm ? this.vrm.scene : gltf.scene;
    if (this.vrm) {
      // The stream poses the raw bones itself; three-vrm must not copy its normalised rig
      // (still at rest) over them on update().
      this.vrm.humanoid.autoUpdateHumanBones = false;
    }
    // Node index → object, then bone → object by the server's naming rule.
    const names = serverNames(gltf.parser.json);
    const byName = new Map();
    this.root.traverse((object) => {
      const index = gltf.parser.associations.get(object)?.nodes;
      if (index === undefined) return;
      const name = names[index];
      if (!byName.has(name)) byName.set(name, object);
      byName.set(`${name}_${index}`, object);
    });
    this.root.updateMatrixWorld(true);
    this.nodes = bones.map((b) => byName.get(b.name) ?? null);
    this.numBound = this.nodes.filter(Boolean).length;
    const boneOfNode = new Map(this.nodes.map((n, i) => [n, i]));
    // Per bone: the bone its node hangs under (-1: a node above the skeleton, which never
    // moves, so its model-space matrix is taken once), and the node's rest scale.
    this.parentBone = this.nodes.map((n) => (n && boneOfNode.has(n.parent) ? boneOfNode.get(n.parent) : -1));
    this.staticParent = this.nodes.map((n) => (n?.parent ? this.modelMatrixOf(n.parent) : new THREE.Matrix4()));
    this.restScale = this.nodes.map((n) => {
      const scale = new THREE.Vector3(1, 1, 1);
      if (n) this.modelMatrixOf(n).decompose(new THREE.Vector3(), new THREE.Quaternion(), scale);
      return scale;
    });
    this.model = this.nodes.map(() => new THREE.Matrix4());
    this.inverse = new THREE.Matrix4();
    this.local = new THREE.Matrix4();
    this.skinnedMeshes = [];
    this.root.traverse((object) => {
      if (cheap && object.isMesh) object.material = cheapen(object.material);
      if (object.isSkinnedMesh) {
        this.skinnedMeshes.push(object);
        // Bounds are those of the rest pose; a walking character leaves them.
        object.frustumCulled = false;
      }
    });
  }

  /** Proxies of the skinned meshes for each fraction of `details` (< 1), built now (load time)
   *  so a change of level later costs nothing: per original mesh, one lighter `SkinnedMesh`
   *  beside it, bound to the same skeleton with the same bind matrix (so driving the joints
   *  drives both) and sharing its material. A mesh that cannot be clustered keeps itself. */
  makeProxies(details) {
    const started = performance.now();
    this.proxies = new Map(); // fraction -> Map(original mesh -> proxy mesh)
    const meshes = this.skinnedMeshes.filter(decimatable);
    this.verticesFull = this.skinnedMeshes.reduce((s, m) => s + m.geometry.attributes.position.count, 0);
    for (const fraction of details.filter((d) => d < 1)) {
      const geometries = clusterMeshes(meshes, fraction);
      const proxies = new Map();
      for (const [mesh, geometry] of geometries) {
        const proxy = new THREE.SkinnedMesh(geometry, mesh.material);
        proxy.name = `${mesh.name} (${Math.round(fraction * 100)} %)`;
        proxy.position.copy(mesh.position);
        proxy.quaternion.copy(mesh.quaternion);
        proxy.scale.copy(mesh.scale);
        proxy.bindMode = mesh.bindMode;
        proxy.bind(mesh.skeleton, mesh.bindMatrix);
        proxy.frustumCulled = false;
        proxy.visible = false;
        mesh.parent.add(proxy);
        proxies.set(mesh, proxy);
      }
      this.proxies.set(fraction, proxies);
    }
    this.detail = 1;
    this.proxyMs = performance.now() - started; // load-time cost, for the report
  }

  /** Shows each skinned mesh at `detail` (a fraction given to `makeProxies`, or 1: the file's
   *  own mesh); `cull`: draw only the front faces of double-sided materials (a closed body
   *  shows no back faces; single-sided ones, such as a back-face outline, stay as they are). */
  setDetail(detail, cull) {
    const shown = this.proxies?.get(detail) ?? new Map();
    for (const mesh of this.skinnedMeshes) mesh.visible = !shown.has(mesh);
    for (const proxies of this.proxies?.values() ?? []) {
      for (const proxy of proxies.values()) proxy.visible = proxies === shown;
    }
    for (const mesh of this.skinnedMeshes) {
      for (const material of [mesh.material].flat()) {
        material.userData.side ??= material.side;
        if (material.userData.side !== THREE.DoubleSide) continue;
        const side = cull ? THREE.FrontSide : THREE.DoubleSide;
        if (material.side !== side) { material.side = side; material.needsUpdate = true; }
      }
    }
    this.detail = shown.size ? detail : 1;
  }

  /** The skinned meshes of the current detail (originals or their proxies), shown or not. */
  levelMeshes() {
    const out = [];
    this.root.traverse((o) => { if (o.isSkinnedMesh && o.visible) out.push(o); });
    return out;
  }

  /** The skinned meshes drawn now: none while the meshes are hidden (stick figures). */
  drawnMeshes() {
    return this.root.visible ? this.levelMeshes() : [];
  }

  /** The node's matrix relative to the model root (root at identity). */
  modelMatrixOf(object) {
    const m = new THREE.Matrix4();
    for (let o = object; o && o !== this.root; o = o.parent) m.premultiply(o.matrix);
    return m;
  }

  /** Poses the model from the viewer's FK: world rotations and positions per bone (bone order,
   *  parents first), in the subject's own space (the model root's). */
  drive(worldR, worldP, dt) {
    for (let i = 0; i < this.nodes.length; i++) {
      const node = this.nodes[i];
      if (!node) continue;
      const m = this.model[i].compose(worldP[i], worldR[i], this.restScale[i]);
      const parent = this.parentBone[i] >= 0 ? this.model[this.parentBone[i]] : this.staticParent[i];
      this.local.multiplyMatrices(this.inverse.copy(parent).invert(), m);
      this.local.decompose(node.position, node.quaternion, node.scale);
    }
    // Spring bones, expressions and constraints of a VRM (its humanoid bones are ours).
    this.vrm?.update(dt);
  }

  /** First bone-matrix texel values of the first skinned mesh drawn (tests compare two
   *  frames). */
  boneMatrixSample() {
    const mesh = this.levelMeshes()[0];
    if (!mesh) return null;
    mesh.skeleton.update();
    return Array.from(mesh.skeleton.boneMatrices.slice(0, 16 * Math.min(mesh.skeleton.bones.length, 8)));
  }
}

/** A Lambert stand-in for a PBR material (or a list of them). */
function cheapen(material) {
  if (Array.isArray(material)) return material.map(cheapen);
  if (!material?.isMeshStandardMaterial) return material;
  const lambert = new THREE.MeshLambertMaterial({
    color: material.color,
    map: material.map,
    emissive: material.emissive,
    emissiveMap: material.emissiveMap,
    transparent: material.transparent,
    opacity: material.opacity,
    alphaTest: material.alphaTest,
    side: material.side,
    vertexColors: material.vertexColors,
  });
  lambert.name = material.name;
  return lambert;
}
