//! Where a body is cut for a graft: the pelvis (waist) and what hangs below it stay with the
//! locomotion, the spine from the waist up and everything on it (arms, neck, head) comes from
//! the graft, and the first few spine bones blend between the two so the join does not show.
//! Found from the analysis's roles, never from names.

use crate::analysis::{Analysis, Role, SectionKind, Side};
use crate::footplant::LegKind;
use crate::skeleton::{BoneId, Skeleton};

use super::GraftError;

/// Core roles whose positions describe each half's posture (the pose distance's joints).
const LOWER_ROLES: [Role; 4] = [Role::UpperLeg, Role::LowerLeg, Role::Foot, Role::Toes];
const UPPER_ROLES: [Role; 6] = [
    Role::Chest,
    Role::Head,
    Role::UpperArm,
    Role::LowerArm,
    Role::Hand,
    Role::Neck(0),
];

/// Which half of the body a bone belongs to in a graft.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Half {
    /// The pelvis, the root above it, legs, tail: taken from the locomotion clip.
    Lower,
    /// Spine above the waist, arms, neck, head: taken from the graft clip.
    Upper,
}

/// The cut of one skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct BodySplit {
    /// The pelvis: the last bone of the lower half on the way up the spine.
    pub waist: BoneId,
    /// Spine bones from just above the waist to the chest, in hierarchy order.
    pub spine: Vec<BoneId>,
    /// Per bone: its half.
    pub halves: Vec<Half>,
    /// Upper-half bones whose local rotation blends from the locomotion's to the graft's,
    /// with the graft's share (rising to 1 along the spine).
    pub blend: Vec<(BoneId, f32)>,
    /// Joints whose positions describe the lower half's posture.
    pub lower_joints: Vec<BoneId>,
    /// Joints whose positions describe the upper half's posture.
    pub upper_joints: Vec<BoneId>,
    /// Hip to ankle, metres (the scale of pose distances).
    pub leg_length: f32,
    /// Left and right hip joints: the pelvis's heading is across them.
    pub hip_joints: (BoneId, BoneId),
    /// The skeleton's up.
    pub up: glam::Vec3,
}

/// The waist (the pelvis) and the spine bones from just above it up to the chest (where the
/// arms attach, or on a sparse spine the arms' parent), waist side first.
fn waist_and_spine(
    skel: &Skeleton,
    analysis: &Analysis,
) -> Result<(BoneId, Vec<BoneId>), GraftError> {
    let find = |role: Role| {
        skel.bone_ids()
            .find(|b| analysis.roles[b.index()].role == role)
    };
    let waist = find(Role::Hips).ok_or_else(|| GraftError::Body("no pelvis found".into()))?;
    // Where the arms attach: the chest, or on a sparse spine (one bone) the arms' parent.
    let arm_root = || {
        find(Role::Clavicle)
            .or_else(|| find(Role::UpperArm))
            .and_then(|b| skel.parent(b))
    };
    let chest = find(Role::Chest)
        .or_else(arm_root)
        .or_else(|| find(Role::Neck(0)))
        .filter(|&c| c != waist)
        .ok_or_else(|| GraftError::Body("no chest (where the arms attach) found".into()))?;
    let mut spine = Vec::new();
    let mut b = chest;
    while b != waist {
        spine.push(b);
        b = skel
            .parent(b)
            .ok_or_else(|| GraftError::Body("the chest does not hang from the pelvis".into()))?;
    }
    spine.reverse();
    Ok((waist, spine))
}

/// The standing legs' longest length and the left and right hind legs' upper bones. The graft
/// cuts at the hips and keeps the legs' own chains: a foot carried beside the body (an IK
/// rig's) is no part of them, so such legs are not grafted.
fn standing_legs(
    skel: &Skeleton,
    analysis: &Analysis,
) -> Result<(f32, BoneId, BoneId), GraftError> {
    let legs: Vec<_> = (crate::footplant::find_legs(skel, analysis).into_iter())
        .filter(|l| !l.carried)
        .collect();
    let leg_length = legs.iter().map(|l| l.length).fold(0.0, f32::max);
    let hind = |side: Side| {
        legs.iter()
            .find(|l| l.kind == LegKind::Hind && l.side == side)
            .map(|l| l.upper)
    };
    let (Some(left), Some(right)) = (hind(Side::Left), hind(Side::Right)) else {
        return Err(GraftError::Body("no left and right legs found".into()));
    };
    if leg_length <= 0.0 {
        return Err(GraftError::Body("no standing legs found".into()));
    }
    Ok((leg_length, left, right))
}

impl BodySplit {
    /// Cuts `skel` (analysed as `analysis`) at the waist, blending the graft in over
    /// `blend_bones` spine bones (at least one).
    pub fn new(
        skel: &Skeleton,
        analysis: &Analysis,
        blend_bones: usize,
    ) -> Result<BodySplit, GraftError> {
        if analysis.roles.len() != skel.num_bones() {
            return Err(GraftError::Body(
                "the analysis is of another skeleton".into(),
            ));
        }
        let (waist, spine) = waist_and_spine(skel, analysis)?;
        let halves = halves(skel, analysis, spine[0]);
        let n = blend_bones.clamp(1, spine.len());
        let blend = spine[..n]
            .iter()
            .enumerate()
            .map(|(k, &b)| (b, (k + 1) as f32 / n as f32))
            .collect();
        let (leg_length, left, right) = standing_legs(skel, analysis)?;
        let joints = |roles: &[Role]| -> Vec<BoneId> {
            skel.bone_ids()
                .filter(|b| roles.contains(&analysis.roles[b.index()].role))
                .collect()
        };
        Ok(BodySplit {
            waist,
            spine,
            halves,
            blend,
            lower_joints: joints(&LOWER_ROLES),
            upper_joints: joints(&UPPER_ROLES),
            leg_length,
            hip_joints: (left, right),
            up: analysis.up,
        })
    }

    /// The half of `bone`.
    pub fn half(&self, bone: BoneId) -> Half {
        self.halves
            .get(bone.index())
            .copied()
            .unwrap_or(Half::Lower)
    }
}

/// Upper: the subtree of the first spine bone above the waist, except legs (3ds Max Biped
/// hangs the thighs under its spine) and whatever hangs from them.
fn halves(skel: &Skeleton, analysis: &Analysis, upper_root: BoneId) -> Vec<Half> {
    let is_leg = |b: BoneId| {
        let r = &analysis.roles[b.index()];
        let leg_role = matches!(
            r.role,
            Role::PelvisSide | Role::UpperLeg | Role::LowerLeg | Role::Foot | Role::Toes
        );
        let leg_section = r
            .section
            .and_then(|s| analysis.sections.get(s as usize))
            .is_some_and(|s| matches!(s.kind, SectionKind::Leg | SectionKind::Tail));
        leg_role || leg_section
    };
    let mut halves = vec![Half::Lower; skel.num_bones()];
    // Parents come first, so one pass sees each parent's half before its children.
    for b in skel.bone_ids() {
        let upper = if b == upper_root {
            true
        } else {
            skel.parent(b)
                .is_some_and(|p| halves[p.index()] == Half::Upper)
                && !is_leg(b)
        };
        if upper {
            halves[b.index()] = Half::Upper;
        }
    }
    halves
}
