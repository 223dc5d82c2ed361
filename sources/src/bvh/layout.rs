//! A BVH file's own hierarchy, and writing motion onto it.
//!
//! Retargeting onto a BVH character must give back a file that loads onto that character:
//! the same joints in the same order, End Sites that stay End Sites, the same channels in the
//! same order per joint, the same offsets in the same units. [`write_bvh_onto`] writes a clip of
//! the skeleton read from such a file with exactly that hierarchy; only the motion is new.

use std::fmt::Write as _;

use glam::{Quat, Vec3};
use rigcast_retarget::{BoneId, Clip, RotationOrder};

use super::Channel;
use crate::error::SourceError;

/// One ROOT, JOINT or End Site as the file declares it, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct LayoutJoint {
    /// The skeleton bone it became.
    pub bone: usize,
    /// Index of the enclosing joint in the layout's list.
    pub parent: Option<usize>,
    /// An End Site (no channels, written as `End Site`).
    pub end_site: bool,
    /// Channels in file order.
    pub channels: Vec<Channel>,
    /// OFFSET in file units, as read.
    pub offset: Vec3,
}

/// A BVH file's hierarchy: joints in file order and the units.
#[derive(Debug, Clone, PartialEq)]
pub struct BvhLayout {
    /// Joints and End Sites in file order.
    pub joints: Vec<LayoutJoint>,
    /// Metres per file unit.
    pub scale: f32,
}

/// Writes `clip` (poses of the skeleton read with `layout`) as BVH with that file's hierarchy.
/// Fails when the clip's skeleton is not the layout's (a different bone count).
pub fn write_bvh_onto(clip: &Clip, layout: &BvhLayout) -> Result<String, SourceError> {
    let n = clip.skeleton.num_bones();
    if layout.joints.len() != n || layout.joints.iter().any(|j| j.bone >= n) {
        return Err(SourceError::InvalidOption {
            reason: format!(
                "the clip has {n} bones but the BVH layout describes {} joints and End Sites",
                layout.joints.len()
            ),
        });
    }
    if !(layout.scale.is_finite() && layout.scale > 0.0) {
        return Err(SourceError::InvalidOption {
            reason: format!("BVH scale must be positive, got {}", layout.scale),
        });
    }
    let children = children_in_file_order(layout);
    let mut out = String::with_capacity(64 * n + clip.num_frames() * n * 30);
    out.push_str("HIERARCHY\n");
    for (i, j) in layout.joints.iter().enumerate() {
        if j.parent.is_none() {
            write_block(&mut out, clip, layout, &children, i, 0);
        }
    }
    // Writing to a String cannot fail.
    let _ = writeln!(out, "MOTION\nFrames: {}", clip.num_frames());
    let _ = writeln!(out, "Frame Time: {}", clip.frame_time_secs);
    let mut line = String::new();
    for pose in &clip.poses {
        line.clear();
        for j in layout.joints.iter().filter(|j| !j.end_site) {
            let t = pose.translations[j.bone] / layout.scale;
            let angles = rotation_channels(&j.channels, pose.rotations[j.bone]);
            let mut rot = angles.iter();
            for c in &j.channels {
                let v = match c {
                    Channel::Xposition => t.x,
                    Channel::Yposition => t.y,
                    Channel::Zposition => t.z,
                    _ => rot.next().copied().unwrap_or(0.0),
                };
                // Writing to a String cannot fail.
                let _ = write!(line, "{v} ");
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    Ok(out)
}

fn children_in_file_order(layout: &BvhLayout) -> Vec<Vec<usize>> {
    let mut children = vec![Vec::new(); layout.joints.len()];
    for (i, j) in layout.joints.iter().enumerate() {
        if let Some(p) = j.parent.filter(|&p| p < layout.joints.len()) {
            children[p].push(i);
        }
    }
    children
}

fn write_block(
    out: &mut String,
    clip: &Clip,
    layout: &BvhLayout,
    children: &[Vec<usize>],
    i: usize,
    depth: usize,
) {
    let j = &layout.joints[i];
    let pad = "\t".repeat(depth);
    let o = j.offset;
    if j.end_site {
        // Writing to a String cannot fail.
        let _ = writeln!(out, "{pad}End Site\n{pad}{{");
        let _ = writeln!(out, "{pad}\tOFFSET {} {} {}", o.x, o.y, o.z);
        let _ = writeln!(out, "{pad}}}");
        return;
    }
    let keyword = if j.parent.is_none() { "ROOT" } else { "JOINT" };
    let name = clip.skeleton.name(BoneId(j.bone as u16));
    // Writing to a String cannot fail.
    let _ = writeln!(out, "{pad}{keyword} {name}\n{pad}{{");
    let _ = writeln!(out, "{pad}\tOFFSET {} {} {}", o.x, o.y, o.z);
    let names: Vec<&str> = j.channels.iter().map(|c| c.name()).collect();
    // Writing to a String cannot fail.
    let _ = writeln!(out, "{pad}\tCHANNELS {} {}", names.len(), names.join(" "));
    for &c in &children[i] {
        write_block(out, clip, layout, children, c, depth + 1);
    }
    // Writing to a String cannot fail.
    let _ = writeln!(out, "{pad}}}");
}

/// The rotation channels' angles (degrees, in channel order) that compose to `q`.
fn rotation_channels(channels: &[Channel], q: Quat) -> Vec<f32> {
    let axes: String = channels
        .iter()
        .filter_map(|c| match c {
            Channel::Xrotation => Some('X'),
            Channel::Yrotation => Some('Y'),
            Channel::Zrotation => Some('Z'),
            _ => None,
        })
        .collect();
    match RotationOrder::from_axes(&axes) {
        Some(order) => order.from_quat(q).iter().map(|a| a.to_degrees()).collect(),
        None => {
            // Fewer than three rotation axes (or a repeated one): the rig cannot hold every
            // rotation; keep the part about its own axes (a three-axis order starting with them).
            let full = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]
                .iter()
                .find(|o| o.starts_with(&axes))
                .and_then(|o| RotationOrder::from_axes(o));
            match full {
                Some(order) => order.from_quat(q)[..axes.len()]
                    .iter()
                    .map(|a| a.to_degrees())
                    .collect(),
                None => vec![0.0; axes.len()],
            }
        }
    }
}
