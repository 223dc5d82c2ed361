//! The splice at the waist: the locomotion's pose with the graft's upper body on it. Both
//! poses are of one skeleton. The lower half (root, pelvis, legs) is the locomotion's as it
//! is, so its footplants survive untouched; upper bones take the graft's local rotations, so
//! arm and head motion relative to the chest are the graft's exactly. The graft's torso is
//! turned about the vertical so that it heads where the locomotion's pelvis heads (the two
//! walkers may face different ways), and the first spine bones blend, in world space, from the
//! locomotion's rotation to the graft's over a few bones, which hides the join: the last
//! blended bone (and so the chest) stands exactly as the graft's turned torso does.

use glam::{Quat, Vec3};

use super::body::{BodySplit, Half};
use crate::fk::{forward_kinematics, WorldTransform};
use crate::pose::Pose;
use crate::skeleton::Skeleton;

/// Splices poses of one skeleton. Build once; [`Splice::apply`] allocates nothing.
#[derive(Debug, Clone)]
pub struct Splice {
    skeleton: Skeleton,
    split: BodySplit,
    lower_worlds: Vec<WorldTransform>,
    upper_worlds: Vec<WorldTransform>,
}

/// Shortest-arc slerp.
fn blend(a: Quat, b: Quat, t: f32) -> Quat {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    a.slerp(b, t).normalize()
}

impl Splice {
    /// A splice on `skeleton` cut by `split`.
    pub fn new(skeleton: &Skeleton, split: BodySplit) -> Splice {
        Splice {
            lower_worlds: vec![WorldTransform::IDENTITY; skeleton.num_bones()],
            upper_worlds: vec![WorldTransform::IDENTITY; skeleton.num_bones()],
            skeleton: skeleton.clone(),
            split,
        }
    }

    /// The cut.
    pub fn split(&self) -> &BodySplit {
        &self.split
    }

    /// Writes `lower`'s pose with `upper`'s upper body into `out`. Poses that do not fit the
    /// skeleton leave `out` unchanged and return false.
    pub fn apply(&mut self, lower: &Pose, upper: &Pose, out: &mut Pose) -> bool {
        let s = &self.skeleton;
        if lower.check(s).is_err() || upper.check(s).is_err() || out.check(s).is_err() {
            return false;
        }
        forward_kinematics(s, lower, &mut self.lower_worlds);
        forward_kinematics(s, upper, &mut self.upper_worlds);
        out.copy_from(lower);
        for (i, (o, u)) in out.rotations.iter_mut().zip(&upper.rotations).enumerate() {
            if self.split.halves[i] == Half::Upper {
                *o = *u;
            }
        }
        // The graft's torso, turned to the locomotion's heading about the vertical (a
        // rotation arc between opposite headings could tilt it), blended in world space along
        // the first spine bones: the last of them is the graft's exactly, so the chest and
        // all above it stand as the graft's do; the locomotion's pelvis stays below.
        let (from, to) = (
            self.heading(&self.upper_worlds),
            self.heading(&self.lower_worlds),
        );
        let up = self.split.up;
        let turn = Quat::from_axis_angle(up, from.cross(to).dot(up).atan2(from.dot(to)));
        let mut parent = s
            .parent(self.split.spine[0])
            .map(|p| self.lower_worlds[p.index()].rotation)
            .unwrap_or(Quat::IDENTITY);
        for &(b, w) in &self.split.blend {
            let i = b.index();
            let world = blend(
                self.lower_worlds[i].rotation,
                turn * self.upper_worlds[i].rotation,
                w,
            );
            out.rotations[i] = (parent.inverse() * world).normalize();
            parent = world;
        }
        true
    }

    /// The pelvis's forward (perpendicular to up), read across the hip joints.
    fn heading(&self, worlds: &[WorldTransform]) -> Vec3 {
        let up = self.split.up;
        let (l, r) = self.split.hip_joints;
        let across = worlds[l.index()].translation - worlds[r.index()].translation;
        let left = (across - up * across.dot(up))
            .try_normalize()
            .unwrap_or_else(|| up.any_orthonormal_vector());
        left.cross(up)
    }
}
