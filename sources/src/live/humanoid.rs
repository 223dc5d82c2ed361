//! The Unity `HumanBodyBones` humanoid: names, hierarchy and default offsets.
//!
//! VMC senders name their bones by `HumanBodyBones` and send local offsets; serial IMU suits
//! attach sensors to such bones. This table gives the parent of each bone (a bone whose parent
//! is not present takes its nearest present ancestor, exactly as Unity's humanoid does for the
//! optional `UpperChest`, `Neck`, toes, eyes, jaw and fingers), and a default rest offset used
//! only when a sender provides no position for a bone.
//!
//! Default offsets are in internal coordinates for a character standing in a T-pose as Unity
//! senders do: facing +Z (Unity +Z too: the two spaces differ by a mirror of X), so its left
//! side is at +X internally (Unity -X).

use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_retarget::{world_transforms, Pose, RawSkeleton, RetargetError, Skeleton, Transform};

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
    b("Spine", 0, [0.0, 0.10, 0.0]),                      // 1
    b("Chest", 1, [0.0, 0.12, 0.0]),                      // 2
    b("UpperChest", 2, [0.0, 0.12, 0.0]),                 // 3
    b("Neck", 3, [0.0, 0.14, 0.0]),                       // 4
    b("Head", 4, [0.0, 0.10, 0.0]),                       // 5
    b("LeftEye", 5, [0.03, 0.07, 0.08]),                  // 6
    b("RightEye", 5, [-0.03, 0.07, 0.08]),                // 7
    b("Jaw", 5, [0.0, 0.0, 0.02]),                        // 8
    b("LeftShoulder", 3, [0.02, 0.10, 0.0]),              // 9
    b("LeftUpperArm", 9, [0.10, 0.0, 0.0]),               // 10
    b("LeftLowerArm", 10, [0.27, 0.0, 0.0]),              // 11
    b("LeftHand", 11, [0.25, 0.0, 0.0]),                  // 12
    b("RightShoulder", 3, [-0.02, 0.10, 0.0]),            // 13
    b("RightUpperArm", 13, [-0.10, 0.0, 0.0]),            // 14
    b("RightLowerArm", 14, [-0.27, 0.0, 0.0]),            // 15
    b("RightHand", 15, [-0.25, 0.0, 0.0]),                // 16
    b("LeftUpperLeg", 0, [0.09, -0.05, 0.0]),             // 17
    b("LeftLowerLeg", 17, [0.0, -0.42, 0.0]),             // 18
    b("LeftFoot", 18, [0.0, -0.42, 0.0]),                 // 19
    b("LeftToes", 19, [0.0, -0.06, 0.12]),                // 20
    b("RightUpperLeg", 0, [-0.09, -0.05, 0.0]),           // 21
    b("RightLowerLeg", 21, [0.0, -0.42, 0.0]),            // 22
    b("RightFoot", 22, [0.0, -0.42, 0.0]),                // 23
    b("RightToes", 23, [0.0, -0.06, 0.12]),               // 24
    b("LeftThumbProximal", 12, [0.02, -0.01, 0.03]),      // 25
    b("LeftThumbIntermediate", 25, [0.03, 0.0, 0.01]),    // 26
    b("LeftThumbDistal", 26, [0.025, 0.0, 0.0]),          // 27
    b("LeftIndexProximal", 12, [0.08, 0.0, 0.025]),       // 28
    b("LeftIndexIntermediate", 28, [0.035, 0.0, 0.0]),    // 29
    b("LeftIndexDistal", 29, [0.025, 0.0, 0.0]),          // 30
    b("LeftMiddleProximal", 12, [0.08, 0.0, 0.005]),      // 31
    b("LeftMiddleIntermediate", 31, [0.04, 0.0, 0.0]),    // 32
    b("LeftMiddleDistal", 32, [0.025, 0.0, 0.0]),         // 33
    b("LeftRingProximal", 12, [0.075, 0.0, -0.015]),      // 34
    b("LeftRingIntermediate", 34, [0.035, 0.0, 0.0]),     // 35
    b("LeftRingDistal", 35, [0.025, 0.0, 0.0]),           // 36
    b("LeftLittleProximal", 12, [0.07, 0.0, -0.03]),      // 37
    b("LeftLittleIntermediate", 37, [0.025, 0.0, 0.0]),   // 38
    b("LeftLittleDistal", 38, [0.02, 0.0, 0.0]),          // 39
    b("RightThumbProximal", 16, [-0.02, -0.01, 0.03]),    // 40
    b("RightThumbIntermediate", 40, [-0.03, 0.0, 0.01]),  // 41
    b("RightThumbDistal", 41, [-0.025, 0.0, 0.0]),        // 42
    b("RightIndexProximal", 16, [-0.08, 0.0, 0.025]),     // 43
    b("RightIndexIntermediate", 43, [-0.035, 0.0, 0.0]),  // 44
    b("RightIndexDistal", 44, [-0.025, 0.0, 0.0]),        // 45
    b("RightMiddleProximal", 16, [-0.08, 0.0, 0.005]),    // 46
    b("RightMiddleIntermediate", 46, [-0.04, 0.0, 0.0]),  // 47
    b("RightMiddleDistal", 47, [-0.025, 0.0, 0.0]),       // 48
    b("RightRingProximal", 16, [-0.075, 0.0, -0.015]),    // 49
    b("RightRingIntermediate", 49, [-0.035, 0.0, 0.0]),   // 50
    b("RightRingDistal", 50, [-0.025, 0.0, 0.0]),         // 51
    b("RightLittleProximal", 16, [-0.07, 0.0, -0.03]),    // 52
    b("RightLittleIntermediate", 52, [-0.025, 0.0, 0.0]), // 53
    b("RightLittleDistal", 53, [-0.02, 0.0, 0.0]),        // 54
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

/// Upper-arm bone names (lower case, letters and digits only) of common conventions: Unity
/// `HumanBodyBones`, Mixamo/BVH (`LeftArm`), Unreal (`upperarm_l`). Matched as suffixes, so
/// prefixed names (`mixamorig:LeftArm`) count too.
const UPPER_ARM_SUFFIXES: [&str; 8] = [
    "leftupperarm",
    "rightupperarm",
    "leftarm",
    "rightarm",
    "upperarml",
    "upperarmr",
    "lupperarm",
    "rupperarm",
];

fn is_upper_arm(name: &str) -> bool {
    let key: String = name
        .chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect();
    UPPER_ARM_SUFFIXES.iter().any(|s| key.ends_with(s))
}

/// The N-pose on `skeleton`: its rest pose (taken to be a T-pose) with each upper arm turned,
/// about the shoulder, to hang straight down (-Y) along the body; everything below the upper
/// arm follows unchanged. Upper arms are found by name (see [`UPPER_ARM_SUFFIXES`]); a
/// skeleton without recognisable upper arms gets its rest pose back.
///
/// IMU suits calibrate against it when the performer finds a T-pose hard to hold.
pub fn n_pose(skeleton: &Skeleton) -> Pose {
    let mut pose = skeleton.rest_pose();
    let world = world_transforms(skeleton, &pose);
    for bone in skeleton.bone_ids() {
        if !is_upper_arm(skeleton.name(bone)) {
            continue;
        }
        // The arm's direction is towards its (first) child, the elbow.
        let Some(&elbow) = skeleton.children(bone).first() else {
            continue;
        };
        let w = world[bone.index()].rotation;
        let dir = (w * skeleton.rest()[elbow.index()].translation).normalize_or_zero();
        if dir == Vec3::ZERO {
            continue;
        }
        // A world-space swing, re-expressed locally: parents keep their rest rotations.
        let swing = Quat::from_rotation_arc(dir, Vec3::NEG_Y);
        let parent = skeleton
            .parent(bone)
            .map_or(Quat::IDENTITY, |p| world[p.index()].rotation);
        pose.rotations[bone.index()] = (parent.inverse() * swing * w).normalize();
    }
    pose
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
    fn n_pose_hangs_the_upper_arms_down() {
        let s = default_humanoid().unwrap();
        let pose = n_pose(&s);
        let world = world_transforms(&s, &pose);
        let rest_world = world_transforms(&s, &s.rest_pose());
        for (arm, elbow, hand) in [
            ("LeftUpperArm", "LeftLowerArm", "LeftHand"),
            ("RightUpperArm", "RightLowerArm", "RightHand"),
        ] {
            let (a, e, h) = (
                s.bone(arm).unwrap().index(),
                s.bone(elbow).unwrap().index(),
                s.bone(hand).unwrap().index(),
            );
            // Rest: the arms point sideways (the table's T-pose), so the test is not vacuous.
            let rest_dir =
                (rest_world[e].translation - rest_world[a].translation).normalize_or_zero();
            assert!(rest_dir.y.abs() < 1e-4, "{arm} not horizontal at rest");
            for (from, to) in [(a, e), (e, h)] {
                let dir = (world[to].translation - world[from].translation).normalize_or_zero();
                let deg = dir.angle_between(Vec3::NEG_Y).to_degrees();
                assert!(deg < 5.0, "{arm}: {deg}° from straight down");
            }
            // The shoulder stays put.
            assert!(world[a].translation.distance(rest_world[a].translation) < 1e-6);
        }
        // Only the upper arms turned.
        let rest = s.rest_pose();
        let changed: Vec<&str> = s
            .bone_ids()
            .filter(|b| pose.rotation(*b).angle_between(rest.rotation(*b)) > 1e-5)
            .map(|b| s.name(b))
            .collect();
        assert_eq!(changed, vec!["LeftUpperArm", "RightUpperArm"]);
        assert!(is_upper_arm("mixamorig:LeftArm") && is_upper_arm("upperarm_r"));
        assert!(!is_upper_arm("LeftForeArm") && !is_upper_arm("LeftLowerArm"));
    }

    #[test]
    fn n_pose_of_a_rotated_rest_still_points_down() {
        // A skeleton whose rest rotations are not identity (e.g. a glTF rig): the shoulder is
        // rotated 90° about Y and the arm offset compensates, so the arm still points -X.
        let mut raw = RawSkeleton::default();
        let hips = raw.add("Hips", None, Transform::from_translation(Vec3::Y));
        let sh = raw.add(
            "LeftShoulder",
            Some(hips),
            Transform {
                translation: Vec3::new(-0.1, 0.4, 0.0),
                rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            },
        );
        let arm = raw.add(
            "LeftUpperArm",
            Some(sh),
            Transform::from_translation(Vec3::new(0.0, 0.0, 0.1)),
        );
        raw.add(
            "LeftLowerArm",
            Some(arm),
            Transform::from_translation(Vec3::new(0.0, 0.0, 0.3)),
        );
        let s = Skeleton::build(&raw).unwrap();
        let w = world_transforms(&s, &n_pose(&s));
        let dir = (w[3].translation - w[2].translation).normalize_or_zero();
        assert!(dir.angle_between(Vec3::NEG_Y).to_degrees() < 5.0, "{dir}");
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
