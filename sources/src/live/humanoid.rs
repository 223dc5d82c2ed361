//! The Unity `HumanBodyBones` humanoid: names, hierarchy and default offsets.
//!
//! VMC senders name their bones by `HumanBodyBones` and send local offsets; serial IMU suits
//! attach sensors to such bones. This table gives the parent of each bone (a bone whose parent
//! is not present takes its nearest present ancestor, exactly as Unity's humanoid does for the
//! optional `UpperChest`, `Neck`, toes, eyes, jaw and fingers), and a default rest offset used
//! only when a sender provides no position for a bone.
//!
//! Default offsets are in internal coordinates for a character standing in a T-pose as Unity
//! senders do: facing -Z internally (Unity +Z, mirrored), so its left side is at -X.

use std::sync::Arc;

use glam::Vec3;
use rigcast_retarget::{RawSkeleton, RetargetError, Skeleton, Transform};

/// One `HumanBodyBones` entry.
#[derive(Debug, Clone, Copy)]
pub struct HumanBone {
    /// Unity name, e.g. `LeftUpperArm`.
    pub name: &'static str,
    /// Index of the parent in [`HUMAN_BONES`]; `None` for `Hips`.
    pub parent: Option<usize>,
    /// Default local offset from the parent, metres, internal coordinates.
    pub default_offset: [f32; 3],
}

const fn b(name: &'static str, parent: usize, o: [f32; 3]) -> HumanBone {
    HumanBone {
        name,
        parent: Some(parent),
        default_offset: o,
    }
}

/// Number of entries in [`HUMAN_BONES`].
pub const NUM_HUMAN_BONES: usize = 55;

/// All `HumanBodyBones` (without `LastBone`), parents before children.
pub const HUMAN_BONES: [HumanBone; NUM_HUMAN_BONES] = [
    HumanBone {
        name: "Hips",
        parent: None,
        default_offset: [0.0, 0.95, 0.0],
    },
    b("Spine", 0, [0.0, 0.10, 0.0]),                     // 1
    b("Chest", 1, [0.0, 0.12, 0.0]),                     // 2
    b("UpperChest", 2, [0.0, 0.12, 0.0]),                // 3
    b("Neck", 3, [0.0, 0.14, 0.0]),                      // 4
    b("Head", 4, [0.0, 0.10, 0.0]),                      // 5
    b("LeftEye", 5, [-0.03, 0.07, -0.08]),               // 6
    b("RightEye", 5, [0.03, 0.07, -0.08]),               // 7
    b("Jaw", 5, [0.0, 0.0, -0.02]),                      // 8
    b("LeftShoulder", 3, [-0.02, 0.10, 0.0]),            // 9
    b("LeftUpperArm", 9, [-0.10, 0.0, 0.0]),             // 10
    b("LeftLowerArm", 10, [-0.27, 0.0, 0.0]),            // 11
    b("LeftHand", 11, [-0.25, 0.0, 0.0]),                // 12
    b("RightShoulder", 3, [0.02, 0.10, 0.0]),            // 13
    b("RightUpperArm", 13, [0.10, 0.0, 0.0]),            // 14
    b("RightLowerArm", 14, [0.27, 0.0, 0.0]),            // 15
    b("RightHand", 15, [0.25, 0.0, 0.0]),                // 16
    b("LeftUpperLeg", 0, [-0.09, -0.05, 0.0]),           // 17
    b("LeftLowerLeg", 17, [0.0, -0.42, 0.0]),            // 18
    b("LeftFoot", 18, [0.0, -0.42, 0.0]),                // 19
    b("LeftToes", 19, [0.0, -0.06, -0.12]),              // 20
    b("RightUpperLeg", 0, [0.09, -0.05, 0.0]),           // 21
    b("RightLowerLeg", 21, [0.0, -0.42, 0.0]),           // 22
    b("RightFoot", 22, [0.0, -0.42, 0.0]),               // 23
    b("RightToes", 23, [0.0, -0.06, -0.12]),             // 24
    b("LeftThumbProximal", 12, [-0.02, -0.01, -0.03]),   // 25
    b("LeftThumbIntermediate", 25, [-0.03, 0.0, -0.01]), // 26
    b("LeftThumbDistal", 26, [-0.025, 0.0, 0.0]),        // 27
    b("LeftIndexProximal", 12, [-0.08, 0.0, -0.025]),    // 28
    b("LeftIndexIntermediate", 28, [-0.035, 0.0, 0.0]),  // 29
    b("LeftIndexDistal", 29, [-0.025, 0.0, 0.0]),        // 30
    b("LeftMiddleProximal", 12, [-0.08, 0.0, -0.005]),   // 31
    b("LeftMiddleIntermediate", 31, [-0.04, 0.0, 0.0]),  // 32
    b("LeftMiddleDistal", 32, [-0.025, 0.0, 0.0]),       // 33
    b("LeftRingProximal", 12, [-0.075, 0.0, 0.015]),     // 34
    b("LeftRingIntermediate", 34, [-0.035, 0.0, 0.0]),   // 35
    b("LeftRingDistal", 35, [-0.025, 0.0, 0.0]),         // 36
    b("LeftLittleProximal", 12, [-0.07, 0.0, 0.03]),     // 37
    b("LeftLittleIntermediate", 37, [-0.025, 0.0, 0.0]), // 38
    b("LeftLittleDistal", 38, [-0.02, 0.0, 0.0]),        // 39
    b("RightThumbProximal", 16, [0.02, -0.01, -0.03]),   // 40
    b("RightThumbIntermediate", 40, [0.03, 0.0, -0.01]), // 41
    b("RightThumbDistal", 41, [0.025, 0.0, 0.0]),        // 42
    b("RightIndexProximal", 16, [0.08, 0.0, -0.025]),    // 43
    b("RightIndexIntermediate", 43, [0.035, 0.0, 0.0]),  // 44
    b("RightIndexDistal", 44, [0.025, 0.0, 0.0]),        // 45
    b("RightMiddleProximal", 16, [0.08, 0.0, -0.005]),   // 46
    b("RightMiddleIntermediate", 46, [0.04, 0.0, 0.0]),  // 47
    b("RightMiddleDistal", 47, [0.025, 0.0, 0.0]),       // 48
    b("RightRingProximal", 16, [0.075, 0.0, 0.015]),     // 49
    b("RightRingIntermediate", 49, [0.035, 0.0, 0.0]),   // 50
    b("RightRingDistal", 50, [0.025, 0.0, 0.0]),         // 51
    b("RightLittleProximal", 16, [0.07, 0.0, 0.03]),     // 52
    b("RightLittleIntermediate", 52, [0.025, 0.0, 0.0]), // 53
    b("RightLittleDistal", 53, [0.02, 0.0, 0.0]),        // 54
];

/// Index of a `HumanBodyBones` name in [`HUMAN_BONES`] (exact, case-sensitive, as VMC sends).
pub fn human_bone_index(name: &str) -> Option<usize> {
    HUMAN_BONES.iter().position(|h| h.name == name)
}

/// Nearest ancestor of `index` for which `present` is true.
pub fn present_parent(index: usize, present: &[bool; NUM_HUMAN_BONES]) -> Option<usize> {
    let mut p = HUMAN_BONES[index].parent;
    while let Some(i) = p {
        if present[i] {
            return Some(i);
        }
        p = HUMAN_BONES[i].parent;
    }
    None
}

/// Builds a skeleton of the present bones with the given local offsets (identity rest
/// rotations: senders' rest pose is the normalised T-pose). Bone names are the Unity names.
/// `Hips` must be present.
pub fn build_humanoid(
    present: &[bool; NUM_HUMAN_BONES],
    offsets: &[Vec3; NUM_HUMAN_BONES],
) -> Result<Skeleton, RetargetError> {
    let mut raw = RawSkeleton::default();
    let mut raw_index = [usize::MAX; NUM_HUMAN_BONES];
    if !present[0] {
        return Err(RetargetError::InvalidMapping {
            reason: "a humanoid needs a Hips bone".into(),
        });
    }
    // HUMAN_BONES lists parents first, so every present parent already has a raw index.
    for (i, h) in HUMAN_BONES.iter().enumerate() {
        if !present[i] {
            continue;
        }
        let parent = present_parent(i, present).map(|p| raw_index[p]);
        raw_index[i] = raw.add(h.name, parent, Transform::from_translation(offsets[i]));
    }
    Skeleton::build(&raw)
}

/// The default full humanoid (all bones, default offsets), e.g. for IMU suits.
pub fn default_humanoid() -> Result<Arc<Skeleton>, RetargetError> {
    build_humanoid(&[true; NUM_HUMAN_BONES], &default_offsets()).map(Arc::new)
}

/// The default offsets as vectors.
pub fn default_offsets() -> [Vec3; NUM_HUMAN_BONES] {
    let mut out = [Vec3::ZERO; NUM_HUMAN_BONES];
    for (o, h) in out.iter_mut().zip(HUMAN_BONES.iter()) {
        *o = Vec3::from_array(h.default_offset);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_consistent() {
        for (i, h) in HUMAN_BONES.iter().enumerate() {
            if let Some(p) = h.parent {
                assert!(p < i, "{} parent after child", h.name);
            }
            assert_eq!(human_bone_index(h.name), Some(i));
            // Left bones sit at -X of their right twins (mirror image).
            if let Some(rest) = h.name.strip_prefix("Left") {
                let r = human_bone_index(&format!("Right{rest}")).unwrap();
                let a = h.default_offset;
                let b = HUMAN_BONES[r].default_offset;
                assert_eq!([a[0], a[1], a[2]], [-b[0], b[1], b[2]], "{}", h.name);
            }
        }
        let s = default_humanoid().unwrap();
        assert_eq!(s.num_bones(), NUM_HUMAN_BONES);
    }

    #[test]
    fn missing_bones_take_nearest_present_ancestor() {
        let mut present = [false; NUM_HUMAN_BONES];
        for name in ["Hips", "Spine", "Chest", "Neck", "Head", "LeftShoulder"] {
            present[human_bone_index(name).unwrap()] = true;
        }
        let s = build_humanoid(&present, &default_offsets()).unwrap();
        let neck = s.bone("Neck").unwrap();
        assert_eq!(s.name(s.parent(neck).unwrap()), "Chest");
        let sh = s.bone("LeftShoulder").unwrap();
        assert_eq!(s.name(s.parent(sh).unwrap()), "Chest");
        present[0] = false;
        assert!(build_humanoid(&present, &default_offsets()).is_err());
    }
}
