// Lighter stand-ins for skinned meshes, made once at load time by vertex clustering.
//
// Under a CPU rasteriser (SwiftShader, llvmpipe) every skinned vertex costs its bone-texture
// fetches and matrix blend in software, so a 28k-vertex character is expensive however few
// pixels it covers. Clustering snaps the mesh onto a grid over its rest pose: all vertices of
// one cell become one vertex, and triangles whose corners fall into fewer than three cells
// vanish. It is linear in the vertex count (milliseconds for a whole character, unlike edge
// collapse), and two choices keep the character recognisable and correctly driven:
// - vertices are only merged when they follow the same dominant bone, so fingers, the two
//   legs and an arm against the body never fuse into one vertex that moves with the wrong bone;
// - a cell's vertex is one real vertex of the cell (the one nearest the cell's mean), with all
//   of its attributes (uv, skin indices and weights), so the proxy skins exactly as the
//   original does at that point.
import * as THREE from 'three';

/** For each vertex, the bone with the largest skin weight (the one it mostly follows). */
function dominantBones(geometry) {
  const index = geometry.attributes.skinIndex;
  const weight = geometry.attributes.skinWeight;
  const out = new Uint16Array(index.count);
  for (let v = 0; v < index.count; v++) {
    let best = 0;
    for (let k = 1; k < index.itemSize; k++) if (weight.getComponent(v, k) > weight.getComponent(v, best)) best = k;
    out[v] = index.getComponent(v, best);
  }
  return out;
}

/** Cluster id of every vertex for `cells` grid cells across the box's longest side. */
function clusterIds(positions, bones, box, cells) {
  const size = box.getSize(new THREE.Vector3());
  const cell = Math.max(size.x, size.y, size.z, 1e-9) / cells;
  const keys = new Map();
  const ids = new Uint32Array(bones.length);
  const span = cells + 1;
  for (let v = 0; v < bones.length; v++) {
    const cx = Math.floor((positions.getX(v) - box.min.x) / cell);
    const cy = Math.floor((positions.getY(v) - box.min.y) / cell);
    const cz = Math.floor((positions.getZ(v) - box.min.z) / cell);
    // Exact in a double for cells ≤ 1024 and bones < 65536.
    const key = ((bones[v] * span + cz) * span + cy) * span + cx;
    let id = keys.get(key);
    if (id === undefined) { id = keys.size; keys.set(key, id); }
    ids[v] = id;
  }
  return { ids, count: keys.size };
}

/** Per cluster, the vertex nearest its mean position. */
function representatives(positions, ids, count) {
  const sum = new Float64Array(3 * count);
  const n = new Uint32Array(count);
  for (let v = 0; v < ids.length; v++) {
    const c = ids[v];
    sum[3 * c] += positions.getX(v); sum[3 * c + 1] += positions.getY(v); sum[3 * c + 2] += positions.getZ(v);
    n[c]++;
  }
  const rep = new Int32Array(count).fill(-1);
  const best = new Float64Array(count).fill(Infinity);
  for (let v = 0; v < ids.length; v++) {
    const c = ids[v];
    const dx = positions.getX(v) - sum[3 * c] / n[c];
    const dy = positions.getY(v) - sum[3 * c + 1] / n[c];
    const dz = positions.getZ(v) - sum[3 * c + 2] / n[c];
    const d = dx * dx + dy * dy + dz * dz;
    if (d < best[c]) { best[c] = d; rep[c] = v; }
  }
  return rep;
}

/** Triangles of `geometry` (per group) mapped onto clusters, collapsed ones dropped. */
function clusteredTriangles(geometry, ids) {
  const index = geometry.index;
  const corner = (i) => (index ? index.getX(i) : i);
  const total = index ? index.count : geometry.attributes.position.count;
  const groups = geometry.groups.length ? geometry.groups : [{ start: 0, count: total, materialIndex: 0 }];
  const out = [];
  const newGroups = [];
  for (const group of groups) {
    const seen = new Set();
    const start = out.length;
    for (let i = group.start; i + 2 < group.start + group.count; i += 3) {
      const a = ids[corner(i)], b = ids[corner(i + 1)], c = ids[corner(i + 2)];
      if (a === b || b === c || a === c) continue;
      // The same three clusters twice (two sides of a thin part collapsed) draw once.
      const key = [a, b, c].sort((x, y) => x - y).join(',');
      if (seen.has(key)) continue;
      seen.add(key);
      out.push(a, b, c);
    }
    newGroups.push({ start, count: out.length - start, materialIndex: group.materialIndex ?? 0 });
  }
  return { triangles: out, groups: newGroups };
}

/** A new geometry of the clusters' representative vertices (every attribute copied). */
function proxyGeometry(geometry, rep, triangles, groups) {
  const proxy = new THREE.BufferGeometry();
  for (const [name, attribute] of Object.entries(geometry.attributes)) {
    const size = attribute.itemSize;
    const array = new attribute.array.constructor(rep.length * size);
    for (let c = 0; c < rep.length; c++) {
      // Raw values (a normalised attribute's integers stay integers).
      for (let k = 0; k < size; k++) array[c * size + k] = attribute.array[rep[c] * size + k];
    }
    proxy.setAttribute(name, new THREE.BufferAttribute(array, size, attribute.normalized));
  }
  proxy.setIndex(triangles);
  for (const g of groups) proxy.addGroup(g.start, g.count, g.materialIndex);
  proxy.boundingBox = geometry.boundingBox?.clone() ?? null;
  proxy.boundingSphere = geometry.boundingSphere?.clone() ?? null;
  return proxy;
}

/** Whether a mesh can be clustered: skinned, no morph targets (their deltas would need the
 *  same treatment), attributes readable (not interleaved). */
export function decimatable(mesh) {
  const g = mesh.geometry;
  return mesh.isSkinnedMesh && g.attributes.skinIndex && g.attributes.skinWeight
    && Object.keys(g.morphAttributes).length === 0
    && Object.values(g.attributes).every((a) => !a.isInterleavedBufferAttribute);
}

/**
 * Proxy geometries for `meshes` (skinned, see `decimatable`) with about `fraction` of their
 * vertices in all: one grid over their common rest-pose box (so all parts of a character are
 * simplified alike), its cell count found by bisection. Returns a Map mesh → geometry.
 */
export function clusterMeshes(meshes, fraction) {
  const box = new THREE.Box3();
  for (const m of meshes) {
    m.geometry.computeBoundingBox();
    box.union(m.geometry.boundingBox);
  }
  const prepared = meshes.map((m) => ({ mesh: m, bones: dominantBones(m.geometry) }));
  const total = prepared.reduce((s, p) => s + p.bones.length, 0);
  const countAt = (cells) => prepared.reduce((s, p) => s + clusterIds(p.mesh.geometry.attributes.position, p.bones, box, cells).count, 0);
  // More cells, more vertices (monotonic enough for bisection on whole cells).
  let lo = 4, hi = 1024;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (countAt(mid) > fraction * total) hi = mid; else lo = mid;
  }
  const out = new Map();
  for (const { mesh, bones } of prepared) {
    const geometry = mesh.geometry;
    const { ids, count } = clusterIds(geometry.attributes.position, bones, box, lo);
    const rep = representatives(geometry.attributes.position, ids, count);
    const { triangles, groups } = clusteredTriangles(geometry, ids);
    out.set(mesh, proxyGeometry(geometry, rep, triangles, groups));
  }
  return out;
}
