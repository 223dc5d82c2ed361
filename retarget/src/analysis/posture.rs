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
    let (positions, frame, used_pose) = if is_posture(&rest) {
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

/// Whether joint positions show a body rather than a folded line of joints.
fn is_posture(pos: &[Vec3]) -> bool {
    !is_degenerate(pos)
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
    let cost = |p: &Vec<Vec3>| -> f32 { p.iter().zip(&median).map(|(a, b)| (*a - *b).length()).sum() };
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
pub(crate) fn frame_pose<'a>(motion: &'a [Pose], frame: Option<usize>) -> Option<&'a Pose> {
    frame.and_then(|i| motion.get(i))
}
