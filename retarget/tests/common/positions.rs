//! World joint positions of a clip's frames, for tests judging motion by where joints are
//! (`retarget/tests/graph.rs`, and `sources/tests/motion_graph_real.rs`, which includes this
//! file by path).

use glam::Vec3;
use rigcast_retarget::{world_transforms, Pose, Skeleton};

/// World joint positions of every frame of `poses`.
pub fn joint_positions(skel: &Skeleton, poses: &[Pose]) -> Vec<Vec<Vec3>> {
    poses
        .iter()
        .map(|p| {
            world_transforms(skel, p)
                .iter()
                .map(|w| w.translation)
                .collect()
        })
        .collect()
}
