//! How tall a figure stands, measured on the posture its own analysis reads (the rest pose
//! when that is a posture, else the first frame: LaFAN1-, Bandai- and Kinect-style BVH fold
//! their rest into a line and keep the posture in the motion's rotations) along the body's own
//! up: from its feet to its head when the analysis finds them, else the up axis it reads from
//! the legs (a Z-up rig measures along Z either way).

use glam::Vec3;
use rigcast_retarget::analysis::{analyze, Analysis, Role, Side, SkeletonView};
use rigcast_retarget::{world_transforms, Pose, Skeleton};

/// A figure's standing height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stature {
    /// Extent of the joints along `up`, in the skeleton's units.
    pub height: f32,
    /// The body's up direction it was measured along (unit).
    pub up: Vec3,
    /// The rest pose is not a posture and the height was measured on the first frame.
    pub from_first_frame: bool,
    /// The figure reads as a two-legged body with feet and a head (the height is a person's
    /// kind of height; a dog's or a snake's says nothing of its file's unit).
    pub two_legged: bool,
}

/// The stature of `skeleton`, read on its rest pose, or on `first` (its first animation frame)
/// when the rest is not a posture. The analysis decides which: it reads both and keeps the
/// more complete body (the rest on ties), so a folded rest its shape test cannot see still
/// yields to the frame.
pub fn stature(skeleton: &Skeleton, first: Option<&Pose>) -> Stature {
    let motion = first.map(std::slice::from_ref).unwrap_or(&[]);
    let a = analyze(&SkeletonView::from_clip(skeleton, motion));
    let feet_up = feet_to_head(&a);
    let two_legged = feet_up.is_some();
    let up = feet_up.unwrap_or(a.up);
    let read = extent_along(&a.positions, up);
    // A rest the analysis kept only because no posture reads as a body (a chain of joints on
    // one line) has no height at all when the line lies across `up`; the first frame, which
    // stands it up, is then the better measure (`read` is 0 there, so any frame is no worse).
    let flat = !a.used_pose && read < FLAT_SHARE * extent_along_any(&a.positions);
    if let Some(pose) = first.filter(|p| flat && p.check(skeleton).is_ok()) {
        let posed: Vec<Vec3> = world_transforms(skeleton, pose)
            .iter()
            .map(|w| w.translation)
            .collect();
        return Stature {
            height: extent_along(&posed, up),
            up,
            from_first_frame: true,
            two_legged,
        };
    }
    Stature {
        height: read,
        up,
        from_first_frame: a.used_pose,
        two_legged,
    }
}

/// Height along `up` under which a kept rest counts as lying flat across it, as a share of
/// the rest's largest extent (a standing body's height is the larger share of it).
const FLAT_SHARE: f32 = 0.05;

/// Extent of `points` along the unit direction `up`.
fn extent_along(points: &[Vec3], up: Vec3) -> f32 {
    let along = points.iter().map(|p| p.dot(up));
    let lo = along.clone().fold(f32::INFINITY, f32::min);
    let hi = along.fold(f32::NEG_INFINITY, f32::max);
    (hi - lo).max(0.0)
}

/// Largest extent of `points` along the three axes.
fn extent_along_any(points: &[Vec3]) -> f32 {
    [Vec3::X, Vec3::Y, Vec3::Z]
        .into_iter()
        .map(|axis| extent_along(points, axis))
        .fold(0.0, f32::max)
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
