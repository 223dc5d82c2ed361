//! Ground-truth roles: a file's own humanoid map (VRM's humanoid extension) overrides what the
//! analysis inferred.
//!
//! The map names each VRM / Unity humanoid bone's skeleton bone. Each named bone gets that
//! role and side at full confidence, so every piece of the mapper's evidence that reads roles
//! and sides (role, side, sequence) follows the file's author rather than geometry. When the
//! truth's sides contradict the inferred ones on most bones, the analysis had the facing
//! direction backwards: forward and left are flipped and every side with them, so bones the
//! map does not name (twists, end joints, extra fingers) and the orientation evidence agree.
//! Bones the analysis had given a role the truth assigns elsewhere are demoted to helpers, so
//! no role is claimed twice.

use super::{Analysis, HumanBone, Role, Side};
use crate::skeleton::{BoneId, Skeleton};

/// Role and side of a humanoid bone. `has_upper_chest`: VRM's `chest` is then the middle
/// spine bone and `upperChest` the one the clavicles hang from (the analysis' `Chest`).
pub fn human_bone_role(h: HumanBone, has_upper_chest: bool) -> (Role, Side) {
    use HumanBone as H;
    let all = HumanBone::ALL;
    let idx = |b: HumanBone| all.iter().position(|x| *x == b).unwrap_or(0);
    let finger = |base: HumanBone, side: Side| {
        let off = idx(h).saturating_sub(idx(base));
        (
            Role::Finger {
                digit: (off / 3) as u8,
                joint: (off % 3) as u8,
            },
            side,
        )
    };
    match h {
        H::Hips => (Role::Hips, Side::Center),
        H::Spine => (Role::Spine, Side::Center),
        H::Chest if has_upper_chest => (Role::SpineMid, Side::Center),
        H::Chest | H::UpperChest => (Role::Chest, Side::Center),
        H::Neck => (Role::Neck(0), Side::Center),
        H::Head => (Role::Head, Side::Center),
        H::Jaw => (Role::Jaw, Side::Center),
        H::LeftEye => (Role::Eye, Side::Left),
        H::RightEye => (Role::Eye, Side::Right),
        H::LeftShoulder => (Role::Clavicle, Side::Left),
        H::RightShoulder => (Role::Clavicle, Side::Right),
        H::LeftUpperArm => (Role::UpperArm, Side::Left),
        H::RightUpperArm => (Role::UpperArm, Side::Right),
        H::LeftLowerArm => (Role::LowerArm, Side::Left),
        H::RightLowerArm => (Role::LowerArm, Side::Right),
        H::LeftHand => (Role::Hand, Side::Left),
        H::RightHand => (Role::Hand, Side::Right),
        H::LeftUpperLeg => (Role::UpperLeg, Side::Left),
        H::RightUpperLeg => (Role::UpperLeg, Side::Right),
        H::LeftLowerLeg => (Role::LowerLeg, Side::Left),
        H::RightLowerLeg => (Role::LowerLeg, Side::Right),
        H::LeftFoot => (Role::Foot, Side::Left),
        H::RightFoot => (Role::Foot, Side::Right),
        H::LeftToes => (Role::Toes, Side::Left),
        H::RightToes => (Role::Toes, Side::Right),
        _ if idx(h) >= idx(H::RightThumbProximal) => finger(H::RightThumbProximal, Side::Right),
        _ => finger(H::LeftThumbProximal, Side::Left),
    }
}

/// Parses the truth's human bone names. VRM 1.0 renamed the thumb joints (its
/// `ThumbMetacarpal` is Unity's `ThumbProximal`), so when the map uses the 1.0 vocabulary its
/// names are read as VRM names first.
pub fn parse_truth(skeleton: &Skeleton, truth: &[(String, String)]) -> Vec<(HumanBone, BoneId)> {
    let vrm1 = truth
        .iter()
        .any(|(h, _)| h.to_ascii_lowercase().contains("metacarpal"));
    truth
        .iter()
        .filter_map(|(human, bone)| {
            let h = if vrm1 {
                HumanBone::ALL
                    .iter()
                    .copied()
                    .find(|b| b.vrm_name().eq_ignore_ascii_case(human))
                    .or_else(|| HumanBone::parse(human))
            } else {
                HumanBone::parse(human)
            }?;
            Some((h, skeleton.bone(bone)?))
        })
        .collect()
}

/// Overrides the analysis with ground-truth roles (human bone name → skeleton bone name;
/// unknown names are ignored). Returns how many bones were set from the truth.
pub fn apply_truth(skeleton: &Skeleton, a: &mut Analysis, truth: &[(String, String)]) -> usize {
    let parsed = parse_truth(skeleton, truth);
    if parsed.is_empty() {
        return 0;
    }
    let upper = parsed.iter().any(|(h, _)| *h == HumanBone::UpperChest);
    let wanted: Vec<(BoneId, Role, Side)> = parsed
        .iter()
        .map(|(h, b)| {
            let (r, s) = human_bone_role(*h, upper);
            (*b, r, s)
        })
        .collect();
    // Facing: if the truth disagrees with most inferred sides, the whole frame was mirrored.
    let (mut agree, mut disagree) = (0, 0);
    for (b, _, s) in &wanted {
        let inferred = a.roles[b.index()].side;
        if *s == Side::Center || inferred == Side::Center {
            continue;
        }
        if inferred == *s {
            agree += 1;
        } else {
            disagree += 1;
        }
    }
    if disagree > agree {
        a.forward = -a.forward;
        a.left = -a.left;
        for r in &mut a.roles {
            r.side = r.side.flipped();
        }
        for s in &mut a.sections {
            s.side = s.side.flipped();
        }
    }
    set_roles(a, &wanted, 1.0);
    // VRM requires the body's core; a map with hips, arms and legs is a humanoid.
    let has = |h: HumanBone| parsed.iter().any(|(x, _)| *x == h);
    if has(HumanBone::Hips)
        && has(HumanBone::LeftUpperArm)
        && has(HumanBone::RightUpperArm)
        && has(HumanBone::LeftUpperLeg)
        && has(HumanBone::RightUpperLeg)
    {
        a.humanoid = true;
    }
    wanted.len()
}

/// Gives each bone of `wanted` its role and side at `confidence`; a role one of them takes
/// is no longer another (first-limb) bone's, which becomes a helper, so no role is claimed
/// twice.
pub(crate) fn set_roles(a: &mut Analysis, wanted: &[(BoneId, Role, Side)], confidence: f32) {
    let named: Vec<bool> = {
        let mut v = vec![false; a.roles.len()];
        for (b, _, _) in wanted {
            v[b.index()] = true;
        }
        v
    };
    // A role the truth gives to one bone is no longer another bone's.
    for (i, r) in a.roles.iter_mut().enumerate() {
        if named[i] || r.limb != 0 {
            continue;
        }
        if wanted
            .iter()
            .any(|(_, role, side)| *role == r.role && *side == r.side)
        {
            r.role = Role::Helper;
        }
    }
    for (b, role, side) in wanted {
        let r = &mut a.roles[b.index()];
        r.role = *role;
        r.side = *side;
        r.limb = 0;
        r.confidence = confidence;
    }
}
