//! Forward kinematics: local pose → world (model-space) transforms, into a caller-owned buffer.

use glam::{Quat, Vec3};

use crate::pose::Pose;
use crate::skeleton::Skeleton;

/// A bone's transform in model (world) space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldTransform {
    /// World rotation.
    pub rotation: Quat,
    /// World position of the bone's origin (its joint), metres.
    pub translation: Vec3,
}

impl WorldTransform {
    /// The identity transform.
    pub const IDENTITY: WorldTransform = WorldTransform {
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
    };

    /// Maps a point from this bone's local frame to world space.
    #[inline]
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.translation + self.rotation * p
    }
}

/// Computes world transforms of every bone of `pose` into `out` (length = number of bones).
/// One forward pass, possible because bones are depth-first (`parent[i] < i`). Allocates nothing.
/// A pose or buffer shorter than the skeleton is a caller bug (see [`Pose::check`]): debug
/// builds assert; release builds fill only the bones all three have rather than panic mid-frame.
pub fn forward_kinematics(skeleton: &Skeleton, pose: &Pose, out: &mut [WorldTransform]) {
    debug_assert_eq!(pose.num_bones(), skeleton.num_bones());
    debug_assert_eq!(out.len(), skeleton.num_bones());
    let n = skeleton
        .num_bones()
        .min(pose.rotations.len())
        .min(pose.translations.len())
        .min(out.len());
    let parents = skeleton.parents();
    for i in 0..n {
        let local_r = pose.rotations[i];
        let local_t = pose.translations[i];
        out[i] = match parents[i] {
            None => WorldTransform {
                rotation: local_r,
                translation: local_t,
            },
            Some(p) => {
                let parent = out[p.index()];
                WorldTransform {
                    rotation: parent.rotation * local_r,
                    translation: parent.translation + parent.rotation * local_t,
                }
            }
        };
    }
}

/// Convenience: world transforms in a new buffer (allocates; not for per-frame use).
pub fn world_transforms(skeleton: &Skeleton, pose: &Pose) -> Vec<WorldTransform> {
    let mut out = vec![WorldTransform::IDENTITY; skeleton.num_bones()];
    forward_kinematics(skeleton, pose, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::vec_close;
    use crate::skeleton::{RawSkeleton, Transform};
    use std::f32::consts::FRAC_PI_2;

    #[test]
    fn arm_bends_at_elbow() {
        let mut raw = RawSkeleton::default();
        let root = raw.add(
            "root",
            None,
            Transform::from_translation(Vec3::new(0.0, 1.0, 0.0)),
        );
        let elbow = raw.add("elbow", Some(root), Transform::from_translation(Vec3::X));
        raw.add("wrist", Some(elbow), Transform::from_translation(Vec3::X));
        let s = Skeleton::build(&raw).expect("valid");
        let mut pose = s.rest_pose();
        let wrist = |pose: &Pose| world_transforms(&s, pose)[2].translation;
        assert!(vec_close(wrist(&pose), Vec3::new(2.0, 1.0, 0.0), 1e-6));
        // 90° about +Z at the elbow swings the wrist from +X to +Y.
        pose.rotations[1] = Quat::from_rotation_z(FRAC_PI_2);
        assert!(vec_close(wrist(&pose), Vec3::new(1.0, 2.0, 0.0), 1e-6));
        // Rotating the root carries everything.
        pose.rotations[0] = Quat::from_rotation_y(FRAC_PI_2);
        pose.translations[0] = Vec3::new(5.0, 1.0, 0.0);
        let w = world_transforms(&s, &pose);
        assert!(vec_close(w[1].translation, Vec3::new(5.0, 1.0, -1.0), 1e-6));
        assert!(vec_close(w[2].translation, Vec3::new(5.0, 2.0, -1.0), 1e-6));
    }
}
