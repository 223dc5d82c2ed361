//! Build-time geometry for rest-posture alignment: which joint each bone "points at", the
//! relative facing of two characters, and the per-bone alignment rotation.
//!
//! Everything here runs once in [`super::Mapping::build`]; nothing is per frame.
//!
//! A bone's *segment* runs from its joint to an end joint: the nearest mapped descendant that
//! continues the chain (so a target bone spanning several source bones, or the reverse, is
//! compared over the same stretch of body), or, when nothing below is mapped, its most
//! chain-like child. Alignment maps the target segment's reference direction onto the source's
//! by a rotation built from two directions (the segment, and a secondary direction that fixes
//! twist), so T-pose vs A-pose vs arbitrary rests do not matter.

use glam::{Mat3, Quat, Vec3};

use crate::fk::WorldTransform;
use crate::skeleton::{BoneId, Skeleton};

/// Bend angles below this (radians, ~10°) count as a straight limb: the bend plane is then too
/// unstable to define twist.
const MIN_BEND_RAD: f32 = 0.17;

/// Size of a posed skeleton: the diagonal of its joints' bounding box (never zero).
pub(crate) fn extent(worlds: &[WorldTransform]) -> f32 {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for w in worlds {
        lo = lo.min(w.translation);
        hi = hi.max(w.translation);
    }
    let d = (hi - lo).length();
    if d.is_finite() && d > 0.0 {
        d
    } else {
        1.0
    }
}

/// True when `d` is `a` or lies below it.
pub(crate) fn is_descendant(skel: &Skeleton, a: BoneId, d: BoneId) -> bool {
    d == a || skel.is_below(d, a)
}

/// Direction the chain arrives at `bone` from: from the nearest ancestor joint that is not at
/// the same place, or +Y (up) for roots, which makes a root's main chain the spine.
pub(crate) fn incoming(skel: &Skeleton, worlds: &[WorldTransform], bone: BoneId, eps: f32) -> Vec3 {
    let p = worlds[bone.index()].translation;
    let mut a = skel.parent(bone);
    while let Some(x) = a {
        let d = p - worlds[x.index()].translation;
        if d.length() > eps {
            return d.normalize_or_zero();
        }
        a = skel.parent(x);
    }
    Vec3::Y
}

/// Among the nearest descendants of `bone` accepted by `accept` whose joints are away from
/// `bone`'s joint, the one continuing the chain most straightly.
pub(crate) fn chain_end(
    skel: &Skeleton,
    worlds: &[WorldTransform],
    bone: BoneId,
    eps: f32,
    accept: &dyn Fn(BoneId) -> bool,
) -> Option<BoneId> {
    let origin = worlds[bone.index()].translation;
    let inc = incoming(skel, worlds, bone, eps);
    let mut best: Option<(f32, BoneId)> = None;
    let mut stack: Vec<BoneId> = skel.children(bone).to_vec();
    while let Some(c) = stack.pop() {
        let d = worlds[c.index()].translation - origin;
        if accept(c) && d.length() > eps {
            let score = d.normalize_or_zero().dot(inc);
            if best.is_none_or(|(s, _)| score > s) {
                best = Some((score, c));
            }
        } else {
            stack.extend_from_slice(skel.children(c));
        }
    }
    best.map(|(_, b)| b)
}

/// `end` itself when its joint is away from `bone`'s; otherwise the chain continued below `end`.
pub(crate) fn distinct_end(
    skel: &Skeleton,
    worlds: &[WorldTransform],
    bone: BoneId,
    end: BoneId,
    eps: f32,
) -> Option<BoneId> {
    let d = worlds[end.index()].translation - worlds[bone.index()].translation;
    if d.length() > eps {
        Some(end)
    } else {
        chain_end(skel, worlds, end, eps, &|_| true)
    }
}

/// Unit direction from `a`'s joint to `b`'s joint.
pub(crate) fn direction(worlds: &[WorldTransform], a: BoneId, b: BoneId) -> Vec3 {
    (worlds[b.index()].translation - worlds[a.index()].translation).normalize_or_zero()
}

/// Fallback direction for a bone without an end (a leaf): the segment arriving at it.
pub(crate) fn leaf_direction(
    skel: &Skeleton,
    worlds: &[WorldTransform],
    bone: BoneId,
    eps: f32,
) -> Vec3 {
    if skel.parent(bone).is_none() {
        return Vec3::ZERO;
    }
    let inc = incoming(skel, worlds, bone, eps);
    // `incoming` answers +Y when every ancestor sits on the joint; that is no direction.
    let mut a = skel.parent(bone);
    while let Some(x) = a {
        if (worlds[bone.index()].translation - worlds[x.index()].translation).length() > eps {
            return inc;
        }
        a = skel.parent(x);
    }
    Vec3::ZERO
}

/// Rotation about +Y that best turns the target's horizontal joint layout onto the source's
/// (2-D Kabsch on pairs of offsets from each side's root joint). Identity when undetermined.
pub(crate) fn relative_yaw(pairs: &[(Vec3, Vec3)]) -> Quat {
    let (mut cos_sum, mut sin_sum) = (0.0f64, 0.0f64);
    for (t, s) in pairs {
        let (tx, tz, sx, sz) = (t.x as f64, t.z as f64, s.x as f64, s.z as f64);
        cos_sum += tx * sx + tz * sz;
        sin_sum += tz * sx - tx * sz;
    }
    if cos_sum.abs() + sin_sum.abs() < 1e-12 {
        return Quat::IDENTITY;
    }
    let yaw = sin_sum.atan2(cos_sum) as f32;
    if yaw == 0.0 {
        Quat::IDENTITY
    } else {
        Quat::from_rotation_y(yaw)
    }
}

/// World axis (forward Z, side X, or up Y) most perpendicular to both directions: a twist
/// reference that means the same thing on both characters once their facing is aligned.
pub(crate) fn twist_axis(a: Vec3, b: Vec3) -> Vec3 {
    let mut best = (f32::INFINITY, Vec3::Z);
    for axis in [Vec3::Z, Vec3::X, Vec3::Y] {
        let worst = a.dot(axis).abs().max(b.dot(axis).abs());
        if worst < best.0 - 1e-4 {
            best = (worst, axis);
        }
    }
    best.1
}

/// True when `secondary` is far enough from `primary` to define a plane (a bent limb).
pub(crate) fn is_bent(primary: Vec3, secondary: Vec3) -> bool {
    secondary != Vec3::ZERO && primary.dot(secondary).clamp(-1.0, 1.0).acos() > MIN_BEND_RAD
}

/// Orthonormal frame with `primary` as first axis and `secondary` (projected) as second.
fn frame(primary: Vec3, secondary: Vec3) -> Option<Quat> {
    let e1 = primary.try_normalize()?;
    let e2 = (secondary - e1 * secondary.dot(e1)).try_normalize()?;
    let e3 = e1.cross(e2);
    Some(Quat::from_mat3(&Mat3::from_cols(e1, e2, e3)).normalize())
}

/// World rotation taking the target's (primary, secondary) pair onto the source's. Falls back to
/// the shortest swing when a secondary is degenerate, and to identity without primaries.
pub(crate) fn align(
    target_primary: Vec3,
    target_secondary: Vec3,
    source_primary: Vec3,
    source_secondary: Vec3,
) -> Quat {
    match (
        frame(target_primary, target_secondary),
        frame(source_primary, source_secondary),
    ) {
        (Some(ft), Some(fs)) => (fs * ft.inverse()).normalize(),
        _ => {
            let (Some(t), Some(s)) = (
                target_primary.try_normalize(),
                source_primary.try_normalize(),
            ) else {
                return Quat::IDENTITY;
            };
            Quat::from_rotation_arc(t, s)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::quat_close;

    #[test]
    fn align_maps_frames() {
        // T-pose arm (+X) onto A-pose arm (45° down), forward as twist reference: a pure roll
        // about +Z of -45°.
        let a_pose = Vec3::new(1.0, -1.0, 0.0).normalize_or_zero();
        let q = align(Vec3::X, Vec3::Z, a_pose, Vec3::Z);
        assert!(quat_close(
            q,
            Quat::from_rotation_z(-std::f32::consts::FRAC_PI_4),
            1e-5
        ));
        assert!((q * Vec3::X - a_pose).length() < 1e-5);
        // Degenerate secondary: shortest swing.
        let q = align(Vec3::X, Vec3::X, Vec3::Y, Vec3::Y);
        assert!((q * Vec3::X - Vec3::Y).length() < 1e-5);
    }

    #[test]
    fn yaw_recovers_a_turn() {
        let turn = Quat::from_rotation_y(1.0);
        let pts = [
            Vec3::new(1.0, 0.0, 0.2),
            Vec3::new(-0.5, 1.0, 0.7),
            Vec3::new(0.1, -1.0, -0.9),
        ];
        let pairs: Vec<(Vec3, Vec3)> = pts.iter().map(|&p| (p, turn * p)).collect();
        assert!(quat_close(relative_yaw(&pairs), turn, 1e-5));
        assert_eq!(relative_yaw(&[]), Quat::IDENTITY);
    }

    #[test]
    fn twist_axis_avoids_both_directions() {
        assert_eq!(twist_axis(Vec3::X, Vec3::NEG_Y), Vec3::Z);
        assert_eq!(twist_axis(Vec3::Z, Vec3::new(0.0, -0.3, 0.95)), Vec3::X);
        assert_eq!(twist_axis(Vec3::Y, Vec3::Y), Vec3::Z);
    }
}
