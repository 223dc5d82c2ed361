//! GLB writer: one node per bone (with parents via `children`), a skin listing every bone (so
//! readers — ours included — find the skeleton), and the clip as one animation with LINEAR
//! rotation channels for every bone and translation channels for roots and moving bones.

use glam::Quat;
use rigcast_retarget::Clip;
use serde_json::{json, Value};

use crate::error::SourceError;

const FLOAT: u32 = 5126;

/// Encodes `clip` as a GLB file.
pub fn write_glb(clip: &Clip) -> Result<Vec<u8>, SourceError> {
    let s = &clip.skeleton;
    let n = s.num_bones();
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
    let mut root = json!({
        "asset": {"version": "2.0", "generator": "rigcast"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "skins": [{"joints": (0..n).collect::<Vec<_>>(), "skeleton": roots.first().copied().unwrap_or(0)}],
    });

    let mut bin: Vec<u8> = Vec::new();
    if !clip.poses.is_empty() {
        let mut views = Vec::new();
        let mut accessors = Vec::new();
        let mut push = |bin: &mut Vec<u8>,
                        data: &[f32],
                        kind: &str,
                        count: usize,
                        minmax: Option<(f32, f32)>| {
            let offset = bin.len();
            for v in data {
                bin.extend_from_slice(&v.to_le_bytes());
            }
            views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4}));
            let mut acc = json!({
                "bufferView": views.len() - 1,
                "componentType": FLOAT,
                "count": count,
                "type": kind,
            });
            if let Some((lo, hi)) = minmax {
                acc["min"] = json!([lo]);
                acc["max"] = json!([hi]);
            }
            accessors.push(acc);
            accessors.len() - 1
        };
        let times: Vec<f32> = (0..clip.num_frames())
            .map(|k| (k as f64 * clip.frame_time_secs) as f32)
            .collect();
        let last = times.last().copied().unwrap_or(0.0);
        let input = push(&mut bin, &times, "SCALAR", times.len(), Some((0.0, last)));
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        for b in s.bone_ids() {
            let i = b.index();
            // Keep consecutive keys in one hemisphere so slerp takes the short way.
            let mut prev = Quat::IDENTITY;
            let mut data = Vec::with_capacity(4 * clip.num_frames());
            for (k, p) in clip.poses.iter().enumerate() {
                let mut q = p.rotations[i].normalize();
                if k > 0 && q.dot(prev) < 0.0 {
                    q = -q;
                }
                prev = q;
                data.extend_from_slice(&q.to_array());
            }
            let out = push(&mut bin, &data, "VEC4", clip.num_frames(), None);
            samplers.push(json!({"input": input, "output": out, "interpolation": "LINEAR"}));
            channels.push(
                json!({"sampler": samplers.len() - 1, "target": {"node": i, "path": "rotation"}}),
            );
            let moves = s.parent(b).is_none()
                || clip.poses.iter().any(|p| {
                    (p.translations[i] - rest[i].translation)
                        .abs()
                        .max_element()
                        > 1e-7
                });
            if moves {
                let data: Vec<f32> = clip
                    .poses
                    .iter()
                    .flat_map(|p| p.translations[i].to_array())
                    .collect();
                let out = push(&mut bin, &data, "VEC3", clip.num_frames(), None);
                samplers.push(json!({"input": input, "output": out, "interpolation": "LINEAR"}));
                channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": i, "path": "translation"}}));
            }
        }
        root["animations"] =
            json!([{"name": clip.name, "samplers": samplers, "channels": channels}]);
        root["accessors"] = json!(accessors);
        root["bufferViews"] = json!(views);
        root["buffers"] = json!([{"byteLength": bin.len()}]);
    }
    while bin.len() & 3 != 0 {
        bin.push(0);
    }
    glb_container(&root, (!bin.is_empty()).then_some(&bin[..]))
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
