//! The BlazePose source skeleton: 22 bones in a T-pose with synthesised hips, spine, chest and
//! neck (BlazePose has no such landmarks), named like VRM humanoid bones so mappers recognise
//! them. Rest local rotations are identity, so a bone's rest direction in world space equals
//! its rest offset — the solver relies on that.

use std::sync::Arc;

use glam::Vec3;
use rigcast_retarget::{BoneId, RawSkeleton, Skeleton, Transform};

use super::error::VisionError;

/// Bone indices in the built skeleton (depth-first order, checked by a test).
#[allow(missing_docs)]
pub mod bone {
    pub const HIPS: usize = 0;
    pub const SPINE: usize = 1;
    pub const CHEST: usize = 2;
    pub const NECK: usize = 3;
    pub const HEAD: usize = 4;
    pub const LEFT_UPPER_ARM: usize = 5;
    pub const LEFT_LOWER_ARM: usize = 6;
    pub const LEFT_HAND: usize = 7;
    pub const RIGHT_UPPER_ARM: usize = 8;
    pub const RIGHT_LOWER_ARM: usize = 9;
    pub const RIGHT_HAND: usize = 10;
    pub const LEFT_UPPER_LEG: usize = 11;
    pub const LEFT_LOWER_LEG: usize = 12;
    pub const LEFT_FOOT: usize = 13;
    pub const LEFT_TOES: usize = 14;
    pub const RIGHT_UPPER_LEG: usize = 15;
    pub const RIGHT_LOWER_LEG: usize = 16;
    pub const RIGHT_FOOT: usize = 17;
    pub const RIGHT_TOES: usize = 18;
    pub const NUM_BONES: usize = 19;
}

/// Height of the hip centre above the floor in the rest pose, metres.
pub const REST_HIP_HEIGHT: f32 = 0.95;

/// (name, parent, rest offset from the parent) for every bone, in depth-first order.
pub const BONES: [(&str, Option<usize>, [f32; 3]); bone::NUM_BONES] = [
    ("hips", None, [0.0, REST_HIP_HEIGHT, 0.0]),
    ("spine", Some(bone::HIPS), [0.0, 0.10, 0.0]),
    ("chest", Some(bone::SPINE), [0.0, 0.20, 0.0]),
    ("neck", Some(bone::CHEST), [0.0, 0.22, 0.0]),
    ("head", Some(bone::NECK), [0.0, 0.10, 0.0]),
    ("leftUpperArm", Some(bone::CHEST), [0.18, 0.22, 0.0]),
    ("leftLowerArm", Some(bone::LEFT_UPPER_ARM), [0.28, 0.0, 0.0]),
    ("leftHand", Some(bone::LEFT_LOWER_ARM), [0.25, 0.0, 0.0]),
    ("rightUpperArm", Some(bone::CHEST), [-0.18, 0.22, 0.0]),
    (
        "rightLowerArm",
        Some(bone::RIGHT_UPPER_ARM),
        [-0.28, 0.0, 0.0],
    ),
    ("rightHand", Some(bone::RIGHT_LOWER_ARM), [-0.25, 0.0, 0.0]),
    ("leftUpperLeg", Some(bone::HIPS), [0.10, 0.0, 0.0]),
    (
        "leftLowerLeg",
        Some(bone::LEFT_UPPER_LEG),
        [0.0, -0.43, 0.0],
    ),
    ("leftFoot", Some(bone::LEFT_LOWER_LEG), [0.0, -0.42, 0.0]),
    ("leftToes", Some(bone::LEFT_FOOT), [0.0, -0.07, 0.14]),
    ("rightUpperLeg", Some(bone::HIPS), [-0.10, 0.0, 0.0]),
    (
        "rightLowerLeg",
        Some(bone::RIGHT_UPPER_LEG),
        [0.0, -0.43, 0.0],
    ),
    ("rightFoot", Some(bone::RIGHT_LOWER_LEG), [0.0, -0.42, 0.0]),
    ("rightToes", Some(bone::RIGHT_FOOT), [0.0, -0.07, 0.14]),
];

/// Builds the BlazePose source skeleton.
pub fn blazepose_skeleton() -> Result<Arc<Skeleton>, VisionError> {
    let mut raw = RawSkeleton::default();
    for (name, parent, t) in BONES {
        raw.add(
            name,
            parent,
            Transform::from_translation(Vec3::from_array(t)),
        );
    }
    let skeleton = Skeleton::build(&raw).map_err(|e| VisionError::Skeleton(e.to_string()))?;
    // The solver indexes bones by the constants above; the build must not reorder them.
    for (i, (name, _, _)) in BONES.iter().enumerate() {
        if skeleton.bone(name) != Some(BoneId(i as u16)) {
            return Err(VisionError::Skeleton(format!(
                "bone {name} moved from index {i}"
            )));
        }
    }
    Ok(Arc::new(skeleton))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn skeleton_builds_in_declared_order() {
        let s = blazepose_skeleton().unwrap();
        assert_eq!(s.num_bones(), bone::NUM_BONES);
        assert_eq!(s.name(BoneId(bone::RIGHT_TOES as u16)), "rightToes");
        assert_eq!(
            s.parent(BoneId(bone::LEFT_HAND as u16)),
            Some(BoneId(bone::LEFT_LOWER_ARM as u16))
        );
    }
}
