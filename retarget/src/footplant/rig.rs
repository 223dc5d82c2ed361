//! Which bones make each leg that stands on the ground, found through the skeleton analysis's
//! roles: hind legs (upper leg, lower leg, foot, toes) and, on quadrupeds, the front legs
//! (upper arm, forearm, hand of an arm section that reaches the ground).

use crate::analysis::{Analysis, Role, SectionKind, Side};
use crate::skeleton::{BoneId, Skeleton};

/// Most legs a rig may stand on (spiders have eight).
pub const MAX_FEET: usize = 8;

/// Hind legs or a quadruped's front legs: feet of one kind pair up across rigs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LegKind {
    /// A leg section (thigh, shin, foot).
    Hind,
    /// An arm section that reaches the ground (a quadruped's front leg).
    Front,
}

/// One standing leg: its three joints for the two-bone IK and the foot's contact joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leg {
    /// Hind or front.
    pub kind: LegKind,
    /// The character's side.
    pub side: Side,
    /// Limb pair index (0 = front-most pair of its kind).
    pub limb: u8,
    /// Hip (or shoulder) joint: the first IK bone.
    pub upper: BoneId,
    /// Knee (or elbow): the second IK bone.
    pub lower: BoneId,
    /// Ankle (or wrist): the IK end; also the heel contact joint.
    pub foot: BoneId,
    /// Ball of the foot (toes joint), when the rig has one.
    pub toes: Option<BoneId>,
    /// Hip to ankle along the bones at the analysis's posture, metres.
    pub length: f32,
    /// The foot hangs beside the body instead of below the shin (an IK-style rig's foot, a
    /// lone bone under the armature root): bending the leg does not move it, so the
    /// retargeter carries it at the shin's end and the lock places it there.
    pub carried: bool,
}

impl Leg {
    /// The key pairing a source foot with a target foot.
    pub fn key(&self) -> (LegKind, Side, u8) {
        (self.kind, self.side, self.limb)
    }
}

/// The first bone with `role` on (`side`, `limb`), below `from` in the hierarchy.
fn find_below(
    skel: &Skeleton,
    analysis: &Analysis,
    role: Role,
    side: Side,
    limb: u8,
    from: BoneId,
) -> Option<BoneId> {
    skel.bone_ids().find(|&b| {
        let r = &analysis.roles[b.index()];
        r.role == role && r.side == side && r.limb == limb && skel.is_below(b, from)
    })
}

/// Every standing leg of `skel` (at most [`MAX_FEET`]), in bone order: its foot below its
/// shin, or a lone foot bone beside the body that continues the shin (an IK-style rig's,
/// [`Leg::carried`]). Empty for a rig without legs (an upper body, a hand, a snake).
pub fn find_legs(skel: &Skeleton, analysis: &Analysis) -> Vec<Leg> {
    legs_of(skel, analysis, false)
}

/// [`find_legs`] for a rig whose plants are only watched (a source's): a foot beside the body
/// with bones of its own below it still stands on the ground, so its leg is found with it.
pub fn find_contact_legs(skel: &Skeleton, analysis: &Analysis) -> Vec<Leg> {
    legs_of(skel, analysis, true)
}

fn legs_of(skel: &Skeleton, analysis: &Analysis, watched: bool) -> Vec<Leg> {
    let mut legs = Vec::new();
    if analysis.roles.len() != skel.num_bones() {
        return legs;
    }
    for b in skel.bone_ids() {
        let r = &analysis.roles[b.index()];
        let kind = match r.role {
            Role::UpperLeg => LegKind::Hind,
            Role::UpperArm if ground_arm(analysis, b) => LegKind::Front,
            _ => continue,
        };
        let (lower_role, foot_role, toe_role) = match kind {
            LegKind::Hind => (Role::LowerLeg, Role::Foot, Some(Role::Toes)),
            LegKind::Front => (Role::LowerArm, Role::Hand, None),
        };
        let Some(lower) = find_below(skel, analysis, lower_role, r.side, r.limb, b) else {
            continue;
        };
        // A foot that does not hang below its shin (a rig whose feet sit beside the legs) is
        // carried at the shin's end when it is a bone alone (nothing below it to carry too).
        let below = find_below(skel, analysis, foot_role, r.side, r.limb, lower);
        let beside = below.is_none().then(|| {
            let (side, limb) = (r.side, r.limb);
            let detached = |f: &BoneId| {
                let fr = &analysis.roles[f.index()];
                fr.role == foot_role && fr.side == side && fr.limb == limb
            };
            (kind == LegKind::Hind)
                .then(|| skel.bone_ids().find(detached))
                .flatten()
                .filter(|&f| watched || skel.children(f).is_empty())
        });
        let found = below.or(beside.flatten());
        let (b, lower, foot) = match (found, kind) {
            (Some(foot), _) => (b, lower, foot),
            // A front leg that ends at its forearm (the hoof is the forearm's far end, with
            // no joint of its own): the chain is shoulder blade, upper arm, forearm, so the
            // joint held is the forearm's top (the carpus), the lowest joint the rig has.
            (None, LegKind::Front) => match skel
                .parent(b)
                .filter(|&p| analysis.roles[p.index()].role == Role::Clavicle)
            {
                Some(clavicle) => (clavicle, b, lower),
                None => continue,
            },
            (None, LegKind::Hind) => continue,
        };
        let toes = toe_role
            .and_then(|t| find_below(skel, analysis, t, r.side, r.limb, foot))
            .or_else(|| first_child_joint(skel, analysis, foot));
        let p = |x: BoneId| analysis.positions[x.index()];
        let length = p(b).distance(p(lower)) + p(lower).distance(p(foot));
        if length <= 1e-4 * analysis.size.max(1e-6) {
            continue;
        }
        legs.push(Leg {
            kind,
            side: r.side,
            limb: r.limb,
            upper: b,
            lower,
            foot,
            toes,
            length,
            carried: !skel.is_below(foot, lower),
        });
        if legs.len() == MAX_FEET {
            break;
        }
    }
    legs
}

/// A front foot's ball: the hand's main child when it is part of the same limb (quadrupeds'
/// hooves and paws often end in one unnamed joint).
fn first_child_joint(skel: &Skeleton, analysis: &Analysis, foot: BoneId) -> Option<BoneId> {
    let c = analysis.main_child.get(foot.index()).copied().flatten()?;
    let far = analysis.positions[c.index()].distance(analysis.positions[foot.index()]);
    (skel.parent(c) == Some(foot) && far > 1e-4 * analysis.size).then_some(c)
}

fn ground_arm(analysis: &Analysis, bone: BoneId) -> bool {
    let Some(s) = analysis.roles[bone.index()].section else {
        return false;
    };
    analysis
        .sections
        .get(s as usize)
        .is_some_and(|sec| sec.kind == SectionKind::Arm && sec.ground)
}
