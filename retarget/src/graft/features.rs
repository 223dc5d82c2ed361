//! Pose features of one body half, so that frames of two clips can be compared: the half's
//! core joints relative to the pelvis, in the pelvis's heading frame (forward, up, left; the
//! heading read across the hip joints), in leg lengths, plus their velocities over a short
//! window (the same posture swinging forward or back is a different gait phase). Both clips
//! are on the same rig by then (the graft retargeted onto the locomotion's), so the joints
//! correspond one to one.

use glam::Vec3;

use super::body::{BodySplit, Half};
use crate::fk::{forward_kinematics, WorldTransform};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// Velocities are weighted by this many seconds (a joint moving one leg length per second
/// counts like a 0.1 leg length offset): speed separates phases, posture dominates.
const VELOCITY_SECS: f32 = 0.1;
/// Velocities are measured over at least this long (mocap jitters frame to frame).
const WINDOW_SECS: f64 = 1.0 / 30.0;

/// One feature vector per frame, `dims` numbers each.
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// Numbers per frame.
    pub dims: usize,
    /// Frame-major values.
    pub data: Vec<f32>,
}

impl Features {
    /// Number of frames.
    pub fn num_frames(&self) -> usize {
        self.data.len().checked_div(self.dims).unwrap_or(0)
    }

    /// One frame's vector.
    pub fn row(&self, frame: usize) -> &[f32] {
        &self.data[frame * self.dims..(frame + 1) * self.dims]
    }

    /// Squared distance between frame `a` of `self` and frame `b` of `other`.
    pub fn distance2(&self, a: usize, other: &Features, b: usize) -> f32 {
        squared(self.row(a), other.row(b))
    }
}

/// Squared Euclidean distance.
pub fn squared(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The pelvis's heading frame at one pose: origin at the waist, forward, up, left.
fn heading_frame(worlds: &[WorldTransform], split: &BodySplit) -> (Vec3, [Vec3; 3]) {
    let up = split.up;
    let (l, r) = split.hip_joints;
    let across = worlds[l.index()].translation - worlds[r.index()].translation;
    let left = (across - up * across.dot(up))
        .try_normalize()
        .unwrap_or_else(|| up.any_orthonormal_vector());
    let forward = left.cross(up);
    (worlds[split.waist.index()].translation, [forward, up, left])
}

/// Features of `half` over `poses` of `skel` (`frame_time_secs` apart).
pub fn features(
    skel: &Skeleton,
    poses: &[Pose],
    frame_time_secs: f64,
    split: &BodySplit,
    half: Half,
) -> Features {
    let joints: &[BoneId] = match half {
        Half::Lower => &split.lower_joints,
        Half::Upper => &split.upper_joints,
    };
    let n = poses.len();
    let per = joints.len() * 3;
    let scale = 1.0 / split.leg_length.max(1e-6);
    let mut local = vec![0.0f32; n * per];
    let mut worlds = vec![WorldTransform::IDENTITY; skel.num_bones()];
    for (f, p) in poses.iter().enumerate() {
        if p.check(skel).is_err() {
            continue;
        }
        forward_kinematics(skel, p, &mut worlds);
        let (origin, axes) = heading_frame(&worlds, split);
        for (j, b) in joints.iter().enumerate() {
            let d = worlds[b.index()].translation - origin;
            for (k, axis) in axes.iter().enumerate() {
                local[f * per + j * 3 + k] = d.dot(*axis) * scale;
            }
        }
    }
    let half_window = ((WINDOW_SECS / frame_time_secs.max(1e-6)) / 2.0)
        .ceil()
        .max(1.0) as usize;
    let dims = per * 2;
    let mut data = vec![0.0f32; n * dims];
    for f in 0..n {
        let (a, b) = (f.saturating_sub(half_window), (f + half_window).min(n - 1));
        let span = ((b - a) as f64 * frame_time_secs) as f32;
        for i in 0..per {
            data[f * dims + i] = local[f * per + i];
            if span > 0.0 {
                let v = (local[b * per + i] - local[a * per + i]) / span;
                data[f * dims + per + i] = v * VELOCITY_SECS;
            }
        }
    }
    Features { dims, data }
}
