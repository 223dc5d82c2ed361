//! Posture: which joint positions the analysis reads.
//!
//! A rest pose is only evidence when it shows a body. Many real files do not: LaFAN1-, Bandai-
//! and Kinect-style BVH put every offset along one local axis, so zero rotation folds the body
//! into a line; others shift offsets or stack joints. When the file has animation, the posture
//! comes from the motion instead: the *medoid* frame, the sampled frame whose root-relative
//! joint positions are closest to the per-joint median over all samples. It is a real frame (a
//! median of positions is not a pose any skeleton can take) and the most typical one, so a
//! single odd frame (a jump, a fall) cannot decide the analysis.

use glam::Vec3;

use super::topology::{is_degenerate, joint_positions};
use super::SkeletonView;
use crate::pose::Pose;

/// Frames sampled from the motion for the medoid (evenly spaced).
const MAX_SAMPLES: usize = 24;

/// The joint positions the analysis uses.
pub(crate) struct Posture {
    /// World joint positions.
    pub positions: Vec<Vec3>,
    /// Index into the view's motion of the frame used, if one was.
    pub frame: Option<usize>,
    /// A pose other than the rest pose was used.
    pub used_pose: bool,
    /// World joint positions of frames sampled evenly from the motion (empty without one):
    /// evidence that a single posture cannot give (which way knees and elbows bend).
    pub samples: Vec<Vec<Vec3>>,
}

/// The postures to try for a view, the preferred first: the rest pose alone when it is one,
/// else the motion's medoid frame and a few frames spread over the motion (the analysis keeps
/// the one that reads as the most complete body).
///
/// [`choose`] alone picks the first of them.
pub(crate) fn candidates(view: &SkeletonView<'_>) -> Vec<Posture> {
    let first = choose(view);
    let Some(medoid) = first.frame else {
        return with_medoid(view, first);
    };
    // A folded rest: besides the medoid, a few frames spread over the motion, so a clip that
    // is mostly a fall or a crouch still offers the analysis a body it can read.
    let skel = view.skeleton;
    let valid: Vec<usize> = (0..view.motion.len())
        .filter(|&i| i != medoid && view.motion[i].check(skel).is_ok())
        .collect();
    let step = valid.len().div_ceil(EXTRA_CANDIDATES).max(1);
    let mut out = vec![first];
    for &i in valid.iter().step_by(step) {
        let positions = joint_positions(skel, Some(&view.motion[i]));
        if is_degenerate(&positions) {
            continue;
        }
        out.push(Posture {
            positions,
            frame: Some(i),
            used_pose: true,
            samples: out[0].samples.clone(),
        });
    }
    out
}

/// A rest that looks like a posture by its shape, and beside it the motion's medoid frame or,
/// without a motion, the view's representative pose (a live source's latest frame): the shape
/// test cannot see every folded rest (one whose mirrored halves lie along opposite signs of the
/// axis, with names that say nothing), so the analysis reads both and keeps the more complete
/// body (the rest on ties).
fn with_medoid(view: &SkeletonView<'_>, rest: Posture) -> Vec<Posture> {
    if rest.used_pose {
        return vec![rest];
    }
    let skel = view.skeleton;
    let valid: Vec<usize> = (0..view.motion.len())
        .filter(|&i| view.motion[i].check(skel).is_ok())
        .collect();
    let (positions, frame) = match medoid(view, &valid) {
        Some(m) => (joint_positions(skel, Some(&view.motion[m])), Some(m)),
        None => match view.pose.filter(|p| p.check(skel).is_ok()) {
            Some(p) => (joint_positions(skel, Some(p)), None),
            None => return vec![rest],
        },
    };
    if is_degenerate(&positions) {
        return vec![rest];
    }
    let frame = Posture {
        positions,
        frame,
        used_pose: true,
        samples: rest.samples.clone(),
    };
    vec![rest, frame]
}

/// Frames tried besides the medoid when the rest is not a posture.
const EXTRA_CANDIDATES: usize = 4;

/// Chooses the posture of a view: the rest pose when it is one, else the motion's medoid
/// frame, else the view's representative pose, else the rest pose anyway.
pub(crate) fn choose(view: &SkeletonView<'_>) -> Posture {
    let skel = view.skeleton;
    let rest = joint_positions(skel, None);
    let valid: Vec<usize> = (0..view.motion.len())
        .filter(|&i| view.motion[i].check(skel).is_ok())
        .collect();
    let step = valid.len().div_ceil(MAX_SAMPLES).max(1);
    let samples: Vec<Vec<Vec3>> = valid
        .iter()
        .step_by(step)
        .map(|&i| joint_positions(skel, Some(&view.motion[i])))
        .collect();
    let (positions, frame, used_pose) = if is_posture(skel, &rest) {
        (rest, None, false)
    } else if let Some(i) = medoid(view, &valid) {
        (joint_positions(skel, Some(&view.motion[i])), Some(i), true)
    } else if let Some(p) = view.pose.filter(|p| p.check(skel).is_ok()) {
        (joint_positions(skel, Some(p)), None, true)
    } else {
        (rest, None, false)
    };
    Posture {
        positions,
        frame,
        used_pose,
        samples,
    }
}

/// Whether the rest pose shows a body rather than a folded line of joints: not all joints on
/// one line, and not a zero-rotation rest whose offsets nearly all lie along one local axis
/// (LaFAN1 / Bandai-Namco BVH: each bone's frame turned so its child sits on its X axis, the
/// posture living entirely in the motion's rotations).
fn is_posture(skel: &crate::skeleton::Skeleton, pos: &[Vec3]) -> bool {
    !is_degenerate(pos) && !folded_rest(skel)
}

/// Share of offsets along one signed local axis above which a zero-rotation rest is folded.
const FOLDED_SHARE: f32 = 0.6;

fn folded_rest(skel: &crate::skeleton::Skeleton) -> bool {
    let rest = skel.rest();
    let turned = rest
        .iter()
        .filter(|t| !t.rotation.abs_diff_eq(glam::Quat::IDENTITY, 1e-4))
        .count();
    // Rigs with real rest rotations (glTF's bones along their local Y) show their posture.
    if turned * 10 > rest.len() {
        return false;
    }
    // Each bone's main child (the one with the largest subtree): in a folded rig its offset
    // lies along the one axis by construction; controls beside the body do not count.
    let n = skel.num_bones();
    let mut size = vec![1usize; n];
    for b in skel.bone_ids().collect::<Vec<_>>().into_iter().rev() {
        if let Some(p) = skel.parent(b) {
            size[p.index()] += size[b.index()];
        }
    }
    let mains = skel.bone_ids().filter_map(|b| {
        skel.children(b)
            .iter()
            .copied()
            .max_by_key(|c| (size[c.index()], std::cmp::Reverse(c.index())))
    });
    let mut counts = [0usize; 6];
    let mut total = 0usize;
    for b in mains {
        let t = rest[b.index()].translation;
        let len = t.length();
        if len < 1e-6 {
            continue;
        }
        total += 1;
        let a = t.abs();
        let (axis, v) = if a.x >= a.y && a.x >= a.z {
            (0, t.x)
        } else if a.y >= a.z {
            (1, t.y)
        } else {
            (2, t.z)
        };
        if v.abs() >= 0.95 * len {
            counts[axis * 2 + usize::from(v < 0.0)] += 1;
        }
    }
    let top = counts.iter().copied().max().unwrap_or(0);
    total >= 4 && top as f32 >= FOLDED_SHARE * total as f32
}

/// The motion's mean posture: per bone, the normalised average of its local rotations over the
/// valid frames (sign-aligned), the roots' headings (their turn about `up`) taken out first, so
/// a walk averages to standing with the arms hanging and each leg between its forward and its
/// backward swing. Translations are the first valid frame's. `None` without valid frames.
pub(crate) fn mean_posture(
    skel: &crate::skeleton::Skeleton,
    motion: &[Pose],
    up: Vec3,
) -> Option<Pose> {
    let up = up.try_normalize().unwrap_or(Vec3::Y);
    let valid: Vec<&Pose> = motion.iter().filter(|p| p.check(skel).is_ok()).collect();
    let first = *valid.first()?;
    let n = skel.num_bones();
    let mut sums = vec![glam::Vec4::ZERO; n];
    for p in &valid {
        for (b, sum) in sums.iter_mut().enumerate() {
            let mut q = p.rotations[b];
            if skel.parents()[b].is_none() {
                let along = up * Vec3::new(q.x, q.y, q.z).dot(up);
                let twist = glam::Quat::from_xyzw(along.x, along.y, along.z, q.w);
                if twist.length_squared() > 1e-12 {
                    q = twist.normalize().inverse() * q;
                }
            }
            let v = glam::Vec4::from(q);
            *sum += if v.dot(*sum) < 0.0 { -v } else { v };
        }
    }
    let mut pose = first.clone();
    for (r, sum) in pose.rotations.iter_mut().zip(&sums) {
        if let Some(v) = sum.try_normalize() {
            *r = glam::Quat::from_vec4(v);
        }
    }
    Some(pose)
}

/// The sampled frame closest (sum of joint distances, root-relative) to the per-joint median.
fn medoid(view: &SkeletonView<'_>, valid: &[usize]) -> Option<usize> {
    if valid.is_empty() {
        return None;
    }
    let step = valid.len().div_ceil(MAX_SAMPLES).max(1);
    let picks: Vec<usize> = valid.iter().copied().step_by(step).collect();
    let frames: Vec<Vec<Vec3>> = picks
        .iter()
        .map(|&i| relative(joint_positions(view.skeleton, Some(&view.motion[i]))))
        .filter(|p| !is_degenerate(p))
        .collect();
    if frames.is_empty() {
        return None;
    }
    let n = frames[0].len();
    let median: Vec<Vec3> = (0..n)
        .map(|j| {
            let axis = |f: fn(Vec3) -> f32| {
                let mut v: Vec<f32> = frames.iter().map(|p| f(p[j])).collect();
                v.sort_by(f32::total_cmp);
                v[v.len() / 2]
            };
            Vec3::new(axis(|p| p.x), axis(|p| p.y), axis(|p| p.z))
        })
        .collect();
    let cost =
        |p: &Vec<Vec3>| -> f32 { p.iter().zip(&median).map(|(a, b)| (*a - *b).length()).sum() };
    let best = (0..frames.len()).min_by(|&a, &b| cost(&frames[a]).total_cmp(&cost(&frames[b])))?;
    // `frames` skipped degenerate samples: find the pick it came from.
    let mut k = 0;
    for &i in &picks {
        let p = relative(joint_positions(view.skeleton, Some(&view.motion[i])));
        if is_degenerate(&p) {
            continue;
        }
        if k == best {
            return Some(i);
        }
        k += 1;
    }
    None
}

/// Positions relative to the first joint (removes the root's travel).
fn relative(mut p: Vec<Vec3>) -> Vec<Vec3> {
    let o = p.first().copied().unwrap_or(Vec3::ZERO);
    for x in &mut p {
        *x -= o;
    }
    p
}

/// The pose of a posture frame (for alignment stages that need the same posture).
pub(crate) fn frame_pose(motion: &[Pose], frame: Option<usize>) -> Option<&Pose> {
    frame.and_then(|i| motion.get(i))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::{RawSkeleton, Skeleton, Transform};

    #[test]
    fn a_t_pose_is_a_posture_and_a_folded_rest_is_not() {
        let e = crate::corpus::get("cmu_max").expect("corpus");
        assert!(is_posture(&e.skeleton, &joint_positions(&e.skeleton, None)));
        // Every main child on its parent's +X: LaFAN1-style. Side branches need not be.
        let mut raw = RawSkeleton::default();
        let hips = raw.add("hips", None, Transform::IDENTITY);
        let mut p = hips;
        for i in 0..4 {
            p = raw.add(
                format!("s{i}"),
                Some(p),
                Transform::from_translation(Vec3::X * 0.2),
            );
        }
        for side in [-1.0f32, 1.0] {
            let mut q = raw.add(
                format!("leg{side}"),
                Some(hips),
                Transform::from_translation(Vec3::new(0.0, 0.0, 0.1 * side)),
            );
            for i in 0..3 {
                q = raw.add(
                    format!("leg{side}_{i}"),
                    Some(q),
                    Transform::from_translation(Vec3::X * 0.4),
                );
            }
        }
        let folded = Skeleton::build(&raw).expect("skeleton");
        assert!(folded_rest(&folded));
        assert!(!is_posture(&folded, &joint_positions(&folded, None)));
    }
}

/// Smallest change of a bone's local rotation over the motion (radians) that counts as moving:
/// well above float noise in a file's written angles, well below any animated joint's swing.
const MOVING_ANGLE: f32 = 0.01;

/// Per bone, whether its local rotation changes over the view's motion (evidence of what a
/// bone is: a BVH End Site or an exporter's end joint never rotates, a head does). `None`
/// when the motion has fewer than two valid frames.
pub(crate) fn moving_bones(view: &SkeletonView<'_>) -> Option<Vec<bool>> {
    let skel = view.skeleton;
    let valid: Vec<&Pose> = view
        .motion
        .iter()
        .filter(|p| p.check(skel).is_ok())
        .collect();
    if valid.len() < 2 {
        return None;
    }
    let step = valid.len().div_ceil(MAX_SAMPLES * 2).max(1);
    let first = valid[0];
    let mut moving = vec![false; skel.num_bones()];
    for p in valid.iter().step_by(step).skip(1) {
        for (b, m) in moving.iter_mut().enumerate() {
            *m = *m || first.rotations[b].angle_between(p.rotations[b]) > MOVING_ANGLE;
        }
    }
    Some(moving)
}
