//! Writing motion onto a glTF character's own document.
//!
//! Retargeting onto a GLB character must give back that character: every node with its name
//! and rest transform, the skin's joint order and inverse bind matrices, the meshes. So the
//! output is the input document with its animations replaced by the retargeted clip: bone-local
//! transforms are turned back into node transforms (undoing what the reader folded in: the
//! armature above the top bones, ancestor scale), all buffers are merged into the GLB binary
//! chunk, and one animation with a rotation channel per bone (and a translation channel per
//! moving bone) is appended.

use glam::{Mat4, Quat, Vec3};
use rigcast_retarget::Clip;
use serde_json::{json, Value};

use super::read::GltfTemplate;
use super::write::{moves_off_rest, rotation_keys, Buffers};
use crate::error::SourceError;

fn bad(message: impl Into<String>) -> SourceError {
    SourceError::Gltf {
        message: message.into(),
    }
}

/// Writes `clip` (poses of the skeleton read with `template`) as a GLB that is the template's
/// document with its animations replaced.
pub fn write_glb_onto(template: &GltfTemplate, clip: &Clip) -> Result<Vec<u8>, SourceError> {
    let n = clip.skeleton.num_bones();
    if template.frames.len() != n {
        return Err(bad(format!(
            "the clip has {n} bones but the glTF template has {}",
            template.frames.len()
        )));
    }
    let mut root = template.json.clone();
    if !root.is_object() {
        return Err(bad("the glTF template has no JSON document"));
    }
    let mut bin = merge_buffers(&mut root, &template.buffers)?;
    for f in &template.frames {
        matrix_to_trs(&mut root, f.node);
    }
    let animation = append_animation(&mut root, &mut bin, template, clip);
    root["animations"] = json!([animation]);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root["buffers"] = json!([{"byteLength": bin.len()}]);
    encode_glb(&root, &bin)
}

/// All buffers become one (the GLB binary chunk): views are re-pointed at their bytes' new
/// offsets, 16-byte aligned so every accessor stays aligned.
fn merge_buffers(root: &mut Value, buffers: &[Vec<u8>]) -> Result<Vec<u8>, SourceError> {
    let mut bin = Vec::new();
    let mut base = Vec::with_capacity(buffers.len());
    for b in buffers {
        while !bin.len().is_multiple_of(16) {
            bin.push(0);
        }
        base.push(bin.len());
        bin.extend_from_slice(b);
    }
    let rebase = |buffer: &mut Value, offset: &mut Value| -> Result<(), SourceError> {
        let index = buffer.as_u64().unwrap_or(0) as usize;
        let at = *base.get(index).ok_or_else(|| {
            bad(format!(
                "a buffer view names buffer {index}, which does not exist"
            ))
        })?;
        *buffer = json!(0);
        *offset = json!(offset.as_u64().unwrap_or(0) as usize + at);
        Ok(())
    };
    if let Some(Value::Array(views)) = root.get_mut("bufferViews") {
        for view in views.iter_mut().filter_map(Value::as_object_mut) {
            let mut buffer = view.remove("buffer").unwrap_or(json!(0));
            let mut offset = view.remove("byteOffset").unwrap_or(json!(0));
            rebase(&mut buffer, &mut offset)?;
            view.insert("buffer".into(), buffer);
            view.insert("byteOffset".into(), offset);
            // meshopt keeps its compressed stream's own buffer reference in the extension.
            for ext in ["EXT_meshopt_compression", "KHR_meshopt_compression"] {
                if let Some(m) = view
                    .get_mut("extensions")
                    .and_then(|e| e.get_mut(ext))
                    .and_then(Value::as_object_mut)
                {
                    let mut buffer = m.remove("buffer").unwrap_or(json!(0));
                    let mut offset = m.remove("byteOffset").unwrap_or(json!(0));
                    rebase(&mut buffer, &mut offset)?;
                    m.insert("buffer".into(), buffer);
                    m.insert("byteOffset".into(), offset);
                }
            }
        }
    }
    Ok(bin)
}

/// Animation channels may not target a node given by `matrix`: such a bone node gets the
/// equivalent translation, rotation and scale.
fn matrix_to_trs(root: &mut Value, node: usize) {
    let Some(n) = root
        .get_mut("nodes")
        .and_then(|v| v.get_mut(node))
        .and_then(Value::as_object_mut)
    else {
        return;
    };
    let Some(m) = n.remove("matrix") else { return };
    let cols: Vec<f32> = m
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(Value::as_f64)
                .map(|v| v as f32)
                .collect()
        })
        .unwrap_or_default();
    if cols.len() != 16 {
        return;
    }
    let (s, r, t) = Mat4::from_cols_slice(&cols).to_scale_rotation_translation();
    n.insert("translation".into(), json!(t.to_array()));
    n.insert("rotation".into(), json!(r.normalize().to_array()));
    n.insert("scale".into(), json!(s.to_array()));
}

/// Appends the clip's data to `bin` and its accessors and views to `root`; returns the
/// animation object.
fn append_animation(
    root: &mut Value,
    bin: &mut Vec<u8>,
    template: &GltfTemplate,
    clip: &Clip,
) -> Value {
    let mut data = Buffers {
        bin: std::mem::take(bin),
        views: take_array(root, "bufferViews"),
        accessors: take_array(root, "accessors"),
    };
    let frames = clip.num_frames().max(1);
    let times: Vec<f32> = (0..frames)
        .map(|k| (k as f64 * clip.frame_time_secs) as f32)
        .collect();
    let last = times.last().copied().unwrap_or(0.0);
    let input = data.push(&times, "SCALAR", times.len(), Some((0.0, last)));
    let s = &clip.skeleton;
    let rest = s.rest();
    let (mut samplers, mut channels) = (Vec::new(), Vec::new());
    let mut sample = |out: usize, node: usize, path: &str| {
        samplers.push(json!({"input": input, "output": out, "interpolation": "LINEAR"}));
        channels
            .push(json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}));
    };
    for b in s.bone_ids() {
        let i = b.index();
        let frame = template.frames[i];
        let node_pose = |k: usize| -> (Vec3, Quat) {
            match clip.poses.get(k) {
                Some(p) => frame.unapply(p.translations[i], p.rotations[i]),
                None => frame.unapply(rest[i].translation, rest[i].rotation),
            }
        };
        let rotations = rotation_keys(frames, |k| node_pose(k).1);
        sample(
            data.push(&rotations, "VEC4", frames, None),
            frame.node,
            "rotation",
        );
        if s.parent(b).is_none() || moves_off_rest(clip, i) {
            let keys: Vec<f32> = (0..frames)
                .flat_map(|k| node_pose(k).0.to_array())
                .collect();
            sample(
                data.push(&keys, "VEC3", frames, None),
                frame.node,
                "translation",
            );
        }
    }
    *bin = data.bin;
    root["bufferViews"] = Value::Array(data.views);
    root["accessors"] = Value::Array(data.accessors);
    json!({"name": clip.name, "samplers": samplers, "channels": channels})
}

fn take_array(root: &mut Value, key: &str) -> Vec<Value> {
    match root.get_mut(key).map(Value::take) {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    }
}

fn encode_glb(root: &Value, bin: &[u8]) -> Result<Vec<u8>, SourceError> {
    super::write::glb_container(root, Some(bin))
}
