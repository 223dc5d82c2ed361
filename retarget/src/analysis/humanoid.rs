//! Canonical humanoid roles (VRM 1.0 / Unity `HumanBodyBones` names) for outputs such as VMC.
//!
//! The analysis gives roles by structure; this module turns them into the fixed vocabulary the
//! humanoid ecosystem uses. When a file carries its own humanoid map (VRM's humanoid extension),
//! that map is ground truth and is passed in as `ground_truth`.

use serde::{Deserialize, Serialize};

use super::{Analysis, Role, Side};
use crate::skeleton::{BoneId, Skeleton};

macro_rules! human_bones {
    ($($v:ident => $unity:literal, $vrm:literal;)*) => {
        /// A Unity `HumanBodyBones` / VRM humanoid bone.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        #[allow(missing_docs)]
        pub enum HumanBone { $($v,)* }

        impl HumanBone {
            /// Every humanoid bone, in Unity's order.
            pub const ALL: &'static [HumanBone] = &[$(HumanBone::$v,)*];
            /// Unity `HumanBodyBones` name (what VMC sends), e.g. `LeftUpperArm`.
            pub fn unity_name(self) -> &'static str {
                match self { $(HumanBone::$v => $unity,)* }
            }
            /// VRM humanoid name, e.g. `leftUpperArm`.
            pub fn vrm_name(self) -> &'static str {
                match self { $(HumanBone::$v => $vrm,)* }
            }
            /// Parses a Unity or VRM name (case-insensitive).
            pub fn parse(name: &str) -> Option<HumanBone> {
                HumanBone::ALL.iter().copied().find(|b| {
                    b.unity_name().eq_ignore_ascii_case(name) || b.vrm_name().eq_ignore_ascii_case(name)
                })
            }
        }
    };
}

human_bones! {
    Hips => "Hips", "hips";
    Spine => "Spine", "spine";
    Chest => "Chest", "chest";
    UpperChest => "UpperChest", "upperChest";
    Neck => "Neck", "neck";
    Head => "Head", "head";
    Jaw => "Jaw", "jaw";
    LeftEye => "LeftEye", "leftEye";
    RightEye => "RightEye", "rightEye";
    LeftShoulder => "LeftShoulder", "leftShoulder";
    LeftUpperArm => "LeftUpperArm", "leftUpperArm";
    LeftLowerArm => "LeftLowerArm", "leftLowerArm";
    LeftHand => "LeftHand", "leftHand";
    RightShoulder => "RightShoulder", "rightShoulder";
    RightUpperArm => "RightUpperArm", "rightUpperArm";
    RightLowerArm => "RightLowerArm", "rightLowerArm";
    RightHand => "RightHand", "rightHand";
    LeftUpperLeg => "LeftUpperLeg", "leftUpperLeg";
    LeftLowerLeg => "LeftLowerLeg", "leftLowerLeg";
    LeftFoot => "LeftFoot", "leftFoot";
    LeftToes => "LeftToes", "leftToes";
    RightUpperLeg => "RightUpperLeg", "rightUpperLeg";
    RightLowerLeg => "RightLowerLeg", "rightLowerLeg";
    RightFoot => "RightFoot", "rightFoot";
    RightToes => "RightToes", "rightToes";
    LeftThumbProximal => "LeftThumbProximal", "leftThumbMetacarpal";
    LeftThumbIntermediate => "LeftThumbIntermediate", "leftThumbProximal";
    LeftThumbDistal => "LeftThumbDistal", "leftThumbDistal";
    LeftIndexProximal => "LeftIndexProximal", "leftIndexProximal";
    LeftIndexIntermediate => "LeftIndexIntermediate", "leftIndexIntermediate";
    LeftIndexDistal => "LeftIndexDistal", "leftIndexDistal";
    LeftMiddleProximal => "LeftMiddleProximal", "leftMiddleProximal";
    LeftMiddleIntermediate => "LeftMiddleIntermediate", "leftMiddleIntermediate";
    LeftMiddleDistal => "LeftMiddleDistal", "leftMiddleDistal";
    LeftRingProximal => "LeftRingProximal", "leftRingProximal";
    LeftRingIntermediate => "LeftRingIntermediate", "leftRingIntermediate";
    LeftRingDistal => "LeftRingDistal", "leftRingDistal";
    LeftLittleProximal => "LeftLittleProximal", "leftLittleProximal";
    LeftLittleIntermediate => "LeftLittleIntermediate", "leftLittleIntermediate";
    LeftLittleDistal => "LeftLittleDistal", "leftLittleDistal";
    RightThumbProximal => "RightThumbProximal", "rightThumbMetacarpal";
    RightThumbIntermediate => "RightThumbIntermediate", "rightThumbProximal";
    RightThumbDistal => "RightThumbDistal", "rightThumbDistal";
    RightIndexProximal => "RightIndexProximal", "rightIndexProximal";
    RightIndexIntermediate => "RightIndexIntermediate", "rightIndexIntermediate";
    RightIndexDistal => "RightIndexDistal", "rightIndexDistal";
    RightMiddleProximal => "RightMiddleProximal", "rightMiddleProximal";
    RightMiddleIntermediate => "RightMiddleIntermediate", "rightMiddleIntermediate";
    RightMiddleDistal => "RightMiddleDistal", "rightMiddleDistal";
    RightRingProximal => "RightRingProximal", "rightRingProximal";
    RightRingIntermediate => "RightRingIntermediate", "rightRingIntermediate";
    RightRingDistal => "RightRingDistal", "rightRingDistal";
    RightLittleProximal => "RightLittleProximal", "rightLittleProximal";
    RightLittleIntermediate => "RightLittleIntermediate", "rightLittleIntermediate";
    RightLittleDistal => "RightLittleDistal", "rightLittleDistal";
}

fn sided(side: Side, left: HumanBone, right: HumanBone) -> Option<HumanBone> {
    match side {
        Side::Left => Some(left),
        Side::Right => Some(right),
        Side::Center => None,
    }
}

fn finger(side: Side, digit: u8, joint: u8) -> Option<HumanBone> {
    if digit > 4 || joint > 2 || side == Side::Center {
        return None;
    }
    let base = match side {
        Side::Left => HumanBone::LeftThumbProximal,
        _ => HumanBone::RightThumbProximal,
    };
    let start = HumanBone::ALL.iter().position(|b| *b == base)?;
    HumanBone::ALL
        .get(start + digit as usize * 3 + joint as usize)
        .copied()
}

/// The canonical humanoid map of a skeleton: each humanoid bone with the skeleton bone playing
/// it. `ground_truth` (VRM humanoid: human bone name → skeleton bone name) wins where given;
/// unknown names in it are ignored. Returns an empty list for non-humanoid skeletons without
/// ground truth. Spine bones: first → Spine, the one below the clavicles → Chest, or
/// UpperChest when there are three or more (then the middle one nearest the top is Chest).
pub fn humanoid_roles(
    skeleton: &Skeleton,
    analysis: &Analysis,
    ground_truth: Option<&[(String, String)]>,
) -> Vec<(HumanBone, BoneId)> {
    let mut out: Vec<(HumanBone, BoneId)> = Vec::new();
    if let Some(gt) = ground_truth {
        for (human, bone) in gt {
            if let (Some(h), Some(b)) = (HumanBone::parse(human), skeleton.bone(bone)) {
                out.push((h, b));
            }
        }
    }
    if !analysis.humanoid && out.is_empty() {
        return out;
    }
    let mids: Vec<BoneId> = skeleton
        .bone_ids()
        .filter(|b| analysis.roles[b.index()].role == Role::SpineMid)
        .collect();
    for b in skeleton.bone_ids() {
        let r = analysis.roles[b.index()];
        if r.limb != 0 && r.role.is_limb() {
            continue;
        }
        if analysis.section_kind(b) == Some(super::SectionKind::Wing) {
            continue;
        }
        use HumanBone as H;
        let h = match r.role {
            Role::Hips => Some(H::Hips),
            Role::Spine => Some(H::Spine),
            Role::SpineMid if mids.last() == Some(&b) => Some(H::Chest),
            Role::Chest if !mids.is_empty() => Some(H::UpperChest),
            Role::Chest => Some(H::Chest),
            Role::Neck(0) => Some(H::Neck),
            Role::Head => Some(H::Head),
            Role::Jaw => Some(H::Jaw),
            Role::Eye => sided(r.side, H::LeftEye, H::RightEye),
            Role::Clavicle => sided(r.side, H::LeftShoulder, H::RightShoulder),
            Role::UpperArm => sided(r.side, H::LeftUpperArm, H::RightUpperArm),
            Role::LowerArm => sided(r.side, H::LeftLowerArm, H::RightLowerArm),
            Role::Hand => sided(r.side, H::LeftHand, H::RightHand),
            Role::UpperLeg => sided(r.side, H::LeftUpperLeg, H::RightUpperLeg),
            Role::LowerLeg => sided(r.side, H::LeftLowerLeg, H::RightLowerLeg),
            Role::Foot => sided(r.side, H::LeftFoot, H::RightFoot),
            Role::Toes => sided(r.side, H::LeftToes, H::RightToes),
            Role::Finger { digit, joint } => finger(r.side, digit, joint),
            _ => None,
        };
        if let Some(h) = h {
            if !out.iter().any(|(x, _)| *x == h) {
                out.push((h, b));
            }
        }
    }
    out.sort_by_key(|(h, _)| *h);
    out
}
