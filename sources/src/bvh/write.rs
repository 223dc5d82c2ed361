//! BVH writer.
//!
//! Every joint gets three rotation channels in one order (ZXY by default); roots get position
//! channels, and so does any other bone whose translation moves in some frame (kept exactly).
//! Leaves named `<parent>_end` that never move are written as End Sites. BVH has no rest
//! rotations, so a skeleton with rotated rest bones (e.g. from glTF) keeps its poses exactly but
//! its rest rotations are dropped. Numbers are written in Rust's shortest round-trip form for
//! `f32`, so read→write→read only loses the Euler conversion's rounding.

use std::fmt::Write as _;

use glam::{Quat, Vec3};
use rigcast_retarget::{BoneId, Clip, Pose, RotationOrder, Skeleton};

use crate::error::SourceError;

/// Options for writing BVH.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BvhWriteOptions {
    /// File units per metre (100 = centimetres, the most common BVH unit).
    pub units_per_metre: f32,
    /// Rotation channel order for every joint.
    pub order: RotationOrder,
}

impl Default for BvhWriteOptions {
    fn default() -> Self {
        BvhWriteOptions {
            units_per_metre: 100.0,
            order: RotationOrder::Zxy,
        }
    }
}

const MOVE_TOLERANCE_M: f32 = 1e-7;

/// Writes `clip` as BVH text.
pub fn write_bvh(clip: &Clip, opts: &BvhWriteOptions) -> Result<String, SourceError> {
    if !(opts.units_per_metre.is_finite() && opts.units_per_metre > 0.0) {
        return Err(SourceError::InvalidOption {
            reason: format!(
                "units_per_metre must be positive, got {}",
                opts.units_per_metre
            ),
        });
    }
    let s = &clip.skeleton;
    let n = s.num_bones();
    let (end_site, has_position) = joint_kinds(clip);
    let mut out = String::with_capacity(64 * n + clip.num_frames() * n * 40);
    out.push_str("HIERARCHY\n");
    let joints = Joints {
        end_site: &end_site,
        has_position: &has_position,
        names: readable_names(s),
    };
    for root in s.roots() {
        write_joint(&mut out, clip, root, 0, &joints, opts);
    }
    // Writing to a String cannot fail.
    let _ = writeln!(out, "MOTION\nFrames: {}", clip.num_frames());
    let _ = writeln!(out, "Frame Time: {}", clip.frame_time_secs);
    for pose in &clip.poses {
        write_frame(&mut out, pose, s, &joints, opts);
    }
    Ok(out)
}

/// Per bone: whether it is written as an End Site (an unmoving, unturned `<parent>_end` leaf),
/// and whether it has position channels (a root, or a bone whose offset moves).
fn joint_kinds(clip: &Clip) -> (Vec<bool>, Vec<bool>) {
    let s = &clip.skeleton;
    let n = s.num_bones();
    let rest = s.rest();
    let moves: Vec<bool> = (0..n)
        .map(|i| {
            clip.poses.iter().any(|p| {
                (p.translations[i] - rest[i].translation)
                    .abs()
                    .max_element()
                    > MOVE_TOLERANCE_M
            })
        })
        .collect();
    let end_site: Vec<bool> = s
        .bone_ids()
        .map(|b| {
            let i = b.index();
            let Some(p) = s.parent(b) else { return false };
            s.children(b).is_empty()
                && s.name(b).starts_with(&format!("{}_end", s.name(p)))
                && !moves[i]
                && rest[i].rotation.abs_diff_eq(Quat::IDENTITY, 1e-6)
                && clip
                    .poses
                    .iter()
                    .all(|pose| pose.rotations[i].abs_diff_eq(Quat::IDENTITY, 1e-6))
        })
        .collect();
    let has_position: Vec<bool> = s
        .bone_ids()
        .map(|b| s.parent(b).is_none() || moves[b.index()])
        .collect();

    (end_site, has_position)
}

/// One frame's channel values, on one line.
fn write_frame(
    out: &mut String,
    pose: &Pose,
    s: &Skeleton,
    joints: &Joints<'_>,
    opts: &BvhWriteOptions,
) {
    let u = opts.units_per_metre;
    let start = out.len();
    for b in s.bone_ids() {
        let i = b.index();
        if joints.end_site[i] {
            continue;
        }
        if joints.has_position[i] {
            let t = pose.translations[i] * u;
            // Writing to a String cannot fail.
            let _ = write!(out, "{} {} {} ", t.x, t.y, t.z);
        }
        let a = opts.order.from_quat(pose.rotations[i]);
        for v in a {
            // Writing to a String cannot fail.
            let _ = write!(out, "{} ", v.to_degrees());
        }
    }
    // The line's trailing space goes: every value was followed by one.
    let end = out[start..].trim_end().len() + start;
    out.truncate(end);
    out.push('\n');
}

/// Per bone: written as an End Site, with position channels, under which name.
struct Joints<'a> {
    end_site: &'a [bool],
    has_position: &'a [bool],
    names: Vec<String>,
}

/// The bones' names as a BVH reader reads them back: a name is the rest of its line, its
/// words joined by one space, so a name holding a newline or a tab (legal in glTF) is written
/// with its words joined by one space; an empty one, or one ending in `{` (which opens the
/// block), gets a stand-in; names that became equal get their bone index appended.
fn readable_names(s: &rigcast_retarget::Skeleton) -> Vec<String> {
    let mut used = std::collections::HashSet::new();
    s.names()
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut n = name.split_whitespace().collect::<Vec<_>>().join(" ");
            if n.is_empty() {
                n = format!("bone{i}");
            }
            if n.ends_with('{') {
                n.push('_');
            }
            if !used.insert(n.clone()) {
                n = format!("{n}_{i}");
                used.insert(n.clone());
            }
            n
        })
        .collect()
}

fn write_joint(
    out: &mut String,
    clip: &Clip,
    bone: BoneId,
    depth: usize,
    joints: &Joints<'_>,
    opts: &BvhWriteOptions,
) {
    let (end_site, has_position) = (joints.end_site, joints.has_position);
    let s = &clip.skeleton;
    let i = bone.index();
    let pad = "\t".repeat(depth);
    let offset: Vec3 = s.rest()[i].translation * opts.units_per_metre;
    if end_site[i] {
        // Writing to a String cannot fail.
        let _ = writeln!(out, "{pad}End Site\n{pad}{{");
        let _ = writeln!(out, "{pad}\tOFFSET {} {} {}", offset.x, offset.y, offset.z);
        let _ = writeln!(out, "{pad}}}");
        return;
    }
    let keyword = if s.parent(bone).is_none() {
        "ROOT"
    } else {
        "JOINT"
    };
    // Writing to a String cannot fail.
    let _ = writeln!(out, "{pad}{keyword} {}\n{pad}{{", joints.names[i]);
    let _ = writeln!(out, "{pad}\tOFFSET {} {} {}", offset.x, offset.y, offset.z);
    let rot: Vec<String> = opts
        .order
        .axes()
        .chars()
        .map(|c| format!("{c}rotation"))
        .collect();
    if has_position[i] {
        // Writing to a String cannot fail.
        let _ = writeln!(
            out,
            "{pad}\tCHANNELS 6 Xposition Yposition Zposition {}",
            rot.join(" ")
        );
    } else {
        // Writing to a String cannot fail.
        let _ = writeln!(out, "{pad}\tCHANNELS 3 {}", rot.join(" "));
    }
    for &c in s.children(bone) {
        write_joint(out, clip, c, depth + 1, joints, opts);
    }
    // Writing to a String cannot fail.
    let _ = writeln!(out, "{pad}}}");
}
