//! How tall a figure stands, measured on the posture its own analysis reads (the rest pose
//! when that is a posture, else the first frame: LaFAN1-, Bandai- and Kinect-style BVH fold
//! their rest into a line and keep the posture in the motion's rotations) along the body's own
//! up: from its feet to its head when the analysis finds them, else the up axis it reads from
//! the legs (a Z-up rig measures along Z either way).

use glam::Vec3;
use rigcast_retarget::analysis::{analyze, Analysis, Role, Side, SkeletonView};
use rigcast_retarget::{Pose, Skeleton};

/// A figure's standing height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stature {
    /// Extent of the joints along `up`, in the skeleton's units.
    pub height: f32,
    /// The body's up direction it was measured along (unit).
    pub up: Vec3,
    /// The rest pose is not a posture and the height was measured on the first frame.
    pub from_first_frame: bool,
}

/// The stature of `skeleton`, read on its rest pose, or on `first` (its first animation frame)
/// when the rest is not a posture. The analysis decides which: it reads both and keeps the
/// more complete body (the rest on ties), so a folded rest its shape test cannot see still
/// yields to the frame.
pub fn stature(skeleton: &Skeleton, first: Option<&Pose>) -> Stature {
    let motion = first.map(std::slice::from_ref).unwrap_or(&[]);
    let a = analyze(&SkeletonView::from_clip(skeleton, motion));
    let up = feet_to_head(&a).unwrap_or(a.up);
    let along = a.positions.iter().map(|p| p.dot(up));
    let lo = along.clone().fold(f32::INFINITY, f32::min);
    let hi = along.fold(f32::NEG_INFINITY, f32::max);
    Stature {
        height: (hi - lo).max(0.0),
        up,
        from_first_frame: a.used_pose,
    }
}

/// A two-legged body's up: from between its feet to its head. Unlike the analysis' axis it
/// holds where roles come from names because the geometry reads as no body (offsets shifted a
/// level), and on a frame where the figure lies down it measures the body's length.
fn feet_to_head(a: &Analysis) -> Option<Vec3> {
    if !a.humanoid {
        return None;
    }
    let at = |role, side| a.find(role, side).map(|b| a.positions[b.index()]);
    let feet = (at(Role::Foot, Side::Left)? + at(Role::Foot, Side::Right)?) * 0.5;
    let d = at(Role::Head, Side::Center)? - feet;
    (d.length() > 0.1 * a.size).then(|| d.normalize_or_zero())
}
