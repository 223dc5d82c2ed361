//! Skeletons as the protocol describes them: a `skeleton` message's bones back into a
//! [`Skeleton`] (for tools that record a stream, and for nodes that relay another node's
//! subjects).

use glam::{Quat, Vec3};
use rigcast_protocol::control::BoneInfo;
use rigcast_retarget::{RawSkeleton, Skeleton, Transform};

/// Rebuilds a skeleton from a `skeleton` message's bones.
pub fn skeleton_from_bones(bones: &[BoneInfo]) -> anyhow::Result<Skeleton> {
    let mut raw = RawSkeleton::default();
    for b in bones {
        raw.add(
            b.name.clone(),
            b.parent.map(|p| p as usize),
            Transform {
                translation: Vec3::from_array(b.rest_translation),
                rotation: Quat::from_array(b.rest_rotation),
            },
        );
    }
    Ok(Skeleton::build(&raw)?)
}
