//! A skinned GLB made by the project, for viewer tests on machines without the shared rigged
//! characters: `skeleton`'s bones as glTF nodes and skin joints (with inverse bind matrices),
//! and one mesh of a tapered four-sided "bone" per parent → child segment, each skinned fully to
//! the parent joint (as Blender draws bones), in one material. Written here rather than with
//! `rigcast_sources`' writer, so the file the viewer loads is independent of the reader that
//! builds the server's skeleton from it.
#![allow(clippy::unwrap_used)]

use glam::{Mat4, Vec3};
use rigcast_retarget::{world_transforms, Skeleton, WorldTransform};
use serde_json::{json, Value};

const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;

/// The GLB bytes.
pub fn skinned_glb(skeleton: &Skeleton) -> Vec<u8> {
    let n = skeleton.num_bones();
    let worlds = world_transforms(skeleton, &skeleton.rest_pose());
    let (nodes, roots) = skeleton_nodes(skeleton);
    let mesh = SegmentMesh::around_bones(skeleton, &worlds);
    let ibm: Vec<f32> = worlds
        .iter()
        .flat_map(|w| {
            Mat4::from_rotation_translation(w.rotation, w.translation)
                .inverse()
                .to_cols_array()
        })
        .collect();

    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut view = |bin: &mut Vec<u8>, bytes: Vec<u8>, target: Option<u32>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let mut v = json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        bin.extend(bytes);
        views.push(v);
        views.len() - 1
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let u16s = |v: &[u16]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let positions = &mesh.positions;
    let flat: Vec<f32> = positions.iter().flat_map(|p: &Vec3| p.to_array()).collect();
    let (min, max) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), p| (a.min(*p), b.max(*p)),
    );
    let pos_view = view(&mut bin, f32s(&flat), Some(34962));
    let joint_view = view(&mut bin, u16s(&mesh.joints.concat()), Some(34962));
    let weight_view = view(&mut bin, f32s(&mesh.weights.concat()), Some(34962));
    let index_view = view(&mut bin, u16s(&mesh.indices), Some(34963));
    let ibm_view = view(&mut bin, f32s(&ibm), None);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let count = positions.len();
    let doc = json!({
        "asset": { "version": "2.0", "generator": "rigcast tests" },
        "scene": 0,
        "scenes": [{ "nodes": roots }],
        "nodes": nodes,
        "skins": [{ "joints": (0..n).collect::<Vec<_>>(), "inverseBindMatrices": 4 }],
        "meshes": [{ "name": "body", "primitives": [{
            "attributes": { "POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2 }, "indices": 3, "material": 0 }] }],
        "materials": [{ "name": "skin", "pbrMetallicRoughness": { "baseColorFactor": [0.85, 0.55, 0.45, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8 } }],
        "accessors": [
            { "bufferView": pos_view, "componentType": FLOAT, "count": count, "type": "VEC3", "min": min.to_array(), "max": max.to_array() },
            { "bufferView": joint_view, "componentType": UNSIGNED_SHORT, "count": count, "type": "VEC4" },
            { "bufferView": weight_view, "componentType": FLOAT, "count": count, "type": "VEC4" },
            { "bufferView": index_view, "componentType": UNSIGNED_SHORT, "count": mesh.indices.len(), "type": "SCALAR" },
            { "bufferView": ibm_view, "componentType": FLOAT, "count": n, "type": "MAT4" },
        ],
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    glb_container(serde_json::to_vec(&doc).unwrap(), &bin)
}

/// One glTF node per bone (rest transform, children from the parent links; the project's
/// writer goes the other way round) plus the mesh's node, and the scene's root nodes.
fn skeleton_nodes(skeleton: &Skeleton) -> (Vec<Value>, Vec<usize>) {
    let mut nodes: Vec<Value> = skeleton
        .rest()
        .iter()
        .zip(skeleton.names())
        .map(|(r, name)| {
            json!({
                "name": name,
                "translation": r.translation.to_array(),
                "rotation": r.rotation.to_array(),
            })
        })
        .collect();
    for b in skeleton.bone_ids() {
        if let Some(p) = skeleton.parent(b) {
            let node = nodes[p.index()].as_object_mut().unwrap();
            let children = node.entry("children").or_insert_with(|| json!([]));
            children.as_array_mut().unwrap().push(json!(b.index()));
        }
    }
    let mut roots: Vec<usize> = skeleton.roots().map(|b| b.index()).collect();
    roots.push(nodes.len());
    nodes.push(json!({ "name": "body", "mesh": 0, "skin": 0 }));
    (nodes, roots)
}

/// A mesh with one spindle per segment, each vertex bound wholly to the segment's parent bone.
struct SegmentMesh {
    positions: Vec<Vec3>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    indices: Vec<u16>,
}

impl SegmentMesh {
    /// Per segment parent → child: a tip at each end and four corners around it.
    fn around_bones(skeleton: &Skeleton, worlds: &[WorldTransform]) -> Self {
        let mut mesh = SegmentMesh {
            positions: Vec::new(),
            joints: Vec::new(),
            weights: Vec::new(),
            indices: Vec::new(),
        };
        for b in skeleton.bone_ids() {
            let Some(p) = skeleton.parent(b) else {
                continue;
            };
            let (from, to) = (worlds[p.index()].translation, worlds[b.index()].translation);
            let axis = to - from;
            let length = axis.length();
            if length < 1e-4 {
                continue;
            }
            let dir = axis / length;
            let u = dir.any_orthonormal_vector();
            let v = dir.cross(u);
            let width = (0.35 * length).clamp(0.03, 0.09);
            let at = from + axis * 0.25;
            let base = mesh.positions.len() as u16;
            mesh.positions.extend([
                from,
                to,
                at + u * width,
                at + v * width,
                at - u * width,
                at - v * width,
            ]);
            for _ in 0..6 {
                mesh.joints.push([p.index() as u16, 0, 0, 0]);
                mesh.weights.push([1.0f32, 0.0, 0.0, 0.0]);
            }
            for k in 0..4u16 {
                let (c, d) = (base + 2 + k, base + 2 + (k + 1) % 4);
                mesh.indices.extend([base, d, c, base + 1, c, d]);
            }
        }
        mesh
    }
}

/// The binary glTF container: header, the JSON chunk (space-padded) and the BIN chunk.
fn glb_container(mut json_bytes: Vec<u8>, bin: &[u8]) -> Vec<u8> {
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + json_bytes.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out
}
