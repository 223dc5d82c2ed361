//! GLB writer: one node per bone (with parents via `children`), a skin listing every bone (so
//! readers — ours included — find the skeleton), and the clip as one animation with LINEAR
//! rotation channels for every bone and translation channels for roots and moving bones.

use glam::Quat;
use rigcast_retarget::{Clip, Skeleton};
use serde_json::{json, Value};

use crate::error::SourceError;

const FLOAT: u32 = 5126;

/// Encodes `clip` as a GLB file.
pub fn write_glb(clip: &Clip) -> Result<Vec<u8>, SourceError> {
    let mut root = skeleton_json(&clip.skeleton);
    let mut buffers = Buffers::default();
    if !clip.poses.is_empty() {
        root["animations"] = json!([animation(clip, &mut buffers)]);
        root["accessors"] = json!(buffers.accessors);
        root["bufferViews"] = json!(buffers.views);
        root["buffers"] = json!([{"byteLength": buffers.bin.len()}]);
    }
    let mut bin = buffers.bin;
    while bin.len() & 3 != 0 {
        bin.push(0);
    }
    glb_container(&root, (!bin.is_empty()).then_some(&bin[..]))
}

/// The document without animation: one node per bone at its rest, the scene's roots, and a
/// skin listing every bone.
fn skeleton_json(s: &Skeleton) -> Value {
    let rest = s.rest();
    let nodes: Vec<Value> = s
        .bone_ids()
        .map(|b| {
            let r = rest[b.index()];
            let mut node = json!({
                "name": s.name(b),
                "translation": r.translation.to_array(),
                "rotation": r.rotation.to_array(),
            });
            let children: Vec<usize> = s.children(b).iter().map(|c| c.index()).collect();
            if !children.is_empty() {
                node["children"] = json!(children);
            }
            node
        })
        .collect();
    let roots: Vec<usize> = s.roots().map(|b| b.index()).collect();
    json!({
        "asset": {"version": "2.0", "generator": "rigcast"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "skins": [{"joints": (0..s.num_bones()).collect::<Vec<_>>(), "skeleton": roots.first().copied().unwrap_or(0)}],
    })
}

/// The binary chunk as it fills, with a buffer view and an accessor for each array.
#[derive(Default)]
pub(super) struct Buffers {
    pub(super) bin: Vec<u8>,
    pub(super) views: Vec<Value>,
    pub(super) accessors: Vec<Value>,
}

impl Buffers {
    /// Appends `data` (4-byte aligned) as `count` elements of `kind`; returns the accessor's
    /// index.
    pub(super) fn push(
        &mut self,
        data: &[f32],
        kind: &str,
        count: usize,
        minmax: Option<(f32, f32)>,
    ) -> usize {
        // A document written onto may hold other data before: floats start on 4 bytes.
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        for v in data {
            self.bin.extend_from_slice(&v.to_le_bytes());
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4}));
        let mut acc = json!({
            "bufferView": self.views.len() - 1,
            "componentType": FLOAT,
            "count": count,
            "type": kind,
        });
        if let Some((lo, hi)) = minmax {
            acc["min"] = json!([lo]);
            acc["max"] = json!([hi]);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }
}

/// The clip as one animation: a rotation channel for every bone, a translation channel for
/// roots and bones that move off their rest.
fn animation(clip: &Clip, buffers: &mut Buffers) -> Value {
    let s = &clip.skeleton;
    let frames = clip.num_frames();
    let times: Vec<f32> = (0..frames)
        .map(|k| (k as f64 * clip.frame_time_secs) as f32)
        .collect();
    let last = times.last().copied().unwrap_or(0.0);
    let input = buffers.push(&times, "SCALAR", times.len(), Some((0.0, last)));
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let mut channel = |output: usize, node: usize, path: &str| {
        samplers.push(json!({"input": input, "output": output, "interpolation": "LINEAR"}));
        channels
            .push(json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}));
    };
    for b in s.bone_ids() {
        let i = b.index();
        let keys = rotation_keys(frames, |k| clip.poses[k].rotations[i]);
        let out = buffers.push(&keys, "VEC4", frames, None);
        channel(out, i, "rotation");
        if s.parent(b).is_none() || moves_off_rest(clip, i) {
            let data: Vec<f32> = clip
                .poses
                .iter()
                .flat_map(|p| p.translations[i].to_array())
                .collect();
            let out = buffers.push(&data, "VEC3", frames, None);
            channel(out, i, "translation");
        }
    }
    json!({"name": clip.name, "samplers": samplers, "channels": channels})
}

/// `frames` rotation keys (x, y, z, w each), consecutive keys kept in one hemisphere so that
/// slerp takes the short way.
pub(super) fn rotation_keys(frames: usize, rotation: impl Fn(usize) -> Quat) -> Vec<f32> {
    let mut prev = Quat::IDENTITY;
    let mut keys = Vec::with_capacity(4 * frames);
    for k in 0..frames {
        let mut q = rotation(k).normalize();
        if k > 0 && q.dot(prev) < 0.0 {
            q = -q;
        }
        prev = q;
        keys.extend_from_slice(&q.to_array());
    }
    keys
}

/// Whether bone `i` leaves its rest translation anywhere in the clip.
pub(super) fn moves_off_rest(clip: &Clip, i: usize) -> bool {
    let rest = clip.skeleton.rest()[i].translation;
    clip.poses
        .iter()
        .any(|p| (p.translations[i] - rest).abs().max_element() > 1e-7)
}

/// A GLB file of `root` and its binary chunk (`None`: no BIN chunk), JSON padded to 4 bytes.
pub(super) fn glb_container(root: &Value, bin: Option<&[u8]>) -> Result<Vec<u8>, SourceError> {
    let bad = |message: String| SourceError::Gltf { message };
    let mut json_bytes =
        serde_json::to_vec(root).map_err(|e| bad(format!("cannot encode JSON: {e}")))?;
    while json_bytes.len() & 3 != 0 {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + bin.map_or(0, |b| 8 + b.len());
    let total_u32 =
        u32::try_from(total).map_err(|_| bad(format!("GLB of {total} bytes exceeds 4 GiB")))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total_u32.to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    if let Some(bin) = bin {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
    }
    Ok(out)
}
