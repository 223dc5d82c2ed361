//! Along one limb: clavicle | upper | lower segment (split by [`fit_chain`]), then the hand or
//! foot, its toes or digits (thumb first, by their position on the palm).

use glam::Vec3;

use super::context::{Builder, Ctx, LimbKind};
use super::limbs::{best_split, chain_splits, split_margins, ChainSplit, NEAR_SPLIT};
use super::vocabulary::{Role, SectionKind};
use super::Side;
use crate::skeleton::BoneId;

/// One limb member to place: its chain root and where it hangs.
#[derive(Debug, Clone, Copy)]
pub(super) struct LimbMember {
    pub(super) root: BoneId,
    pub(super) side: Side,
    pub(super) kind: LimbKind,
    pub(super) limb_index: u8,
    pub(super) ground: bool,
    pub(super) parent_sec: Option<usize>,
    /// For an arm of an upright body: how far from the midline the legs hang (their sockets'
    /// offset), which a shoulder joint is no nearer to.
    pub(super) hips_offset: Option<f32>,
}

/// Assigns roles along one limb member (arm, leg or wing) and its extremity and digits.
pub(super) fn limb_roles(ctx: &Ctx<'_>, out: &mut Builder, member: LimbMember) {
    let chain = ctx.topo.chain(member.root);
    let fixed = branch_point(ctx, &chain);
    let is_leg = member.kind == LimbKind::Leg;
    let (limb_kind, _) = section_kinds(member.kind);
    let splits = fit_member(ctx, &chain, fixed, member);
    let Some(split) = best_split(&splits) else {
        out.add_section(
            limb_kind,
            member.side,
            member.limb_index,
            chain.clone(),
            member.parent_sec,
            member.ground,
        );
        let role = if is_leg {
            Role::UpperLeg
        } else {
            Role::UpperArm
        };
        out.roles[chain[0].index()].role = role;
        out.roles[chain[0].index()].confidence = 0.3;
        return;
    };
    let conf = (0.95 * (-split.cost).exp()).clamp(0.2, 0.95);
    split_doubts(out, &chain, &splits, &split);
    let e = split.extremity.min(chain.len());
    let li = out.add_section(
        limb_kind,
        member.side,
        member.limb_index,
        chain[..e].to_vec(),
        member.parent_sec,
        member.ground,
    );
    segment_roles(out, &chain, &split, is_leg, conf);
    if e < chain.len() {
        let fixed_in_rest = fixed.filter(|&f| f >= e).map(|f| f - e);
        extremity_roles(ctx, out, member, &chain[e..], fixed_in_rest, li, conf);
    }
}

/// The split's doubts, for the mapper to carry: each bone that a split nearly as cheap reads
/// otherwise (a clavicle or an upper arm, a thigh or a shin, by proportions alone), as strong
/// as that reading is likely against the one chosen (e^-(cost difference): 1 for a tie).
fn split_doubts(out: &mut Builder, chain: &[BoneId], splits: &[ChainSplit], best: &ChainSplit) {
    let margins = split_margins(splits, best, chain.len());
    for (&b, &d) in chain.iter().zip(&margins) {
        if d >= NEAR_SPLIT {
            continue;
        }
        let strength = (-d).exp();
        out.doubts.push(super::Doubt {
            reason: format!(
                "its limb's bones split nearly as well another way ({d:.2} dearer, fit cost {:.2})",
                best.cost
            ),
            strength,
            bones: vec![b],
        });
    }
}

/// The limb's and its extremity's section kinds.
fn section_kinds(kind: LimbKind) -> (SectionKind, SectionKind) {
    match kind {
        LimbKind::Leg => (SectionKind::Leg, SectionKind::Foot),
        LimbKind::Wing => (SectionKind::Wing, SectionKind::Hand),
        _ => (SectionKind::Arm, SectionKind::Hand),
    }
}

/// Where the chain branches into digits (two or more significant children, from its third
/// bone on), moved one bone on when the branching bone's palm hangs below it.
fn branch_point(ctx: &Ctx<'_>, chain: &[BoneId]) -> Option<usize> {
    chain
        .iter()
        .enumerate()
        .skip(2)
        .find(|(_, &b)| ctx.significant_children(b).len() >= 2)
        .map(|(i, _)| i)
        .map(|i| if palms_below(ctx, chain, i) { i + 1 } else { i })
}

/// Splits the chain into clavicle | upper | lower | extremity by bone lengths and directions.
fn fit_member(
    ctx: &Ctx<'_>,
    chain: &[BoneId],
    fixed: Option<usize>,
    member: LimbMember,
) -> Vec<ChainSplit> {
    let lengths: Vec<f32> = chain.iter().map(|b| ctx.topo.length[b.index()]).collect();
    // A joint bends where two consecutive bones stop being collinear. Segments of one
    // anatomical bone stay in line however it moves; a clavicle and an upper arm in line in
    // a T-pose do not once the arm swings. A bend at rest costs a group 1; one measured over
    // the motion's frames outweighs any proportion (whose cost saturates at 2).
    let bent: Vec<f32> = (0..chain.len())
        .map(|i| {
            if i == 0 {
                0.0
            } else if ctx.samples.iter().any(|s| bends_at(ctx, s, chain, i))
                || leaf_turns(ctx, chain[i])
            {
                MOTION_BEND_COST
            } else if bends_at(ctx, ctx.pos, chain, i) {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    let is_leg = member.kind == LimbKind::Leg;
    let ratio = if is_leg { 1.05 } else { 1.12 };
    tracing::trace!(
        "limb {:?} {:?} chain {:?} len {:?} fixed {:?}",
        member.kind as u8,
        member.side,
        chain.iter().map(|b| ctx.skel.name(*b)).collect::<Vec<_>>(),
        lengths,
        fixed
    );
    let start: Vec<f32> = if is_leg {
        let spans = spans_girdle(ctx, chain[0]);
        vec![if spans { GIRDLE_AS_THIGH_COST } else { 0.0 }]
    } else {
        narrow_shoulders(ctx, chain, member)
    };
    // A leg's branch point may be the toes (claws) rather than the ankle: let the fit choose
    // the foot anywhere up to the branch.
    match fixed {
        Some(f) if is_leg => chain_splits(&lengths[..=f], &bent[..=f], None, ratio, &start),
        _ => chain_splits(&lengths, &bent, fixed, ratio, &start),
    }
}

/// Per chain bone of an upright body's arm, what reading its joint as the shoulder costs a
/// split: the shoulder joints sit at least as far from the midline as the hip sockets (human
/// shoulders ~2 times their width, the zoo's rigs 1.0-2.7), a clavicle's inner end near the
/// midline (0.0-0.96 of it). Nothing at the hips' offset, as much as a bent joint at half of it
/// or nearer: a cartoon's clavicle as long as its short upper arm, read without motion, is not
/// the upper arm.
fn narrow_shoulders(ctx: &Ctx<'_>, chain: &[BoneId], member: LimbMember) -> Vec<f32> {
    let (Some(hips), Some(p)) = (member.hips_offset, ctx.skel.parent(member.root)) else {
        return Vec::new();
    };
    let left = ctx.up.cross(ctx.forward).normalize_or_zero();
    chain
        .iter()
        .take(3)
        .map(|b| {
            let off = (ctx.pos[b.index()] - ctx.pos[p.index()]).dot(left).abs();
            MOTION_BEND_COST * (2.0 * (1.0 - off / hips)).clamp(0.0, 1.0)
        })
        .collect()
}

/// How far from the midline a pair of legs hangs from `parent` (on the centerline): the first
/// joint down each leg's chain that leaves the midline (a pelvis side's or a zero-length thigh
/// helper's joint sits on it), the nearer of the two legs; `None` when they never leave it
/// within their first bones.
pub(super) fn hips_offset(
    ctx: &Ctx<'_>,
    parent: BoneId,
    members: &[(BoneId, Side)],
) -> Option<f32> {
    let left = ctx.up.cross(ctx.forward).normalize_or_zero();
    let off = |b: BoneId| {
        (ctx.pos[b.index()] - ctx.pos[parent.index()])
            .dot(left)
            .abs()
    };
    members
        .iter()
        .map(|&(m, _)| {
            ctx.topo
                .chain(m)
                .iter()
                .take(3)
                .map(|&b| off(b))
                .find(|&o| o > 0.01 * ctx.size)
        })
        .collect::<Option<Vec<f32>>>()?
        .into_iter()
        .reduce(f32::min)
}

/// What reading a girdle bone as the thigh costs a leg's split: as much as grouping across a
/// joint that bends in the motion, more than any proportion.
const GIRDLE_AS_THIGH_COST: f32 = MOTION_BEND_COST;

/// Whether a limb's first bone spans the girdle: its joint sits on the body's joint it hangs
/// from and it runs across the body more than down, to where the limb hangs (a hip bone from
/// the pelvis' joint to the socket, a zero-length thigh helper's segment). A thigh hangs from
/// the socket; a short-legged rig's proportions alone would read the girdle as the thigh.
fn spans_girdle(ctx: &Ctx<'_>, b: BoneId) -> bool {
    let (Some(p), Some(c)) = (ctx.skel.parent(b), ctx.topo.main[b.index()]) else {
        return false;
    };
    let seg = ctx.pos[c.index()] - ctx.pos[b.index()];
    let down = -seg.dot(ctx.up);
    let across = (seg + ctx.up * down).length();
    ctx.is_coincident(b) && ctx.pos[p.index()] != ctx.pos[c.index()] && across > down.max(0.0)
}

/// Whether `b` is a leaf that turns in the motion: the joint it hangs from bends, though no
/// child's position can show it (a glTF forearm ending the arm).
fn leaf_turns(ctx: &Ctx<'_>, b: BoneId) -> bool {
    ctx.topo.main[b.index()].is_none()
        && !ctx.samples.is_empty()
        && ctx.moving.is_some_and(|m| m[b.index()])
}

/// What grouping two bones across a joint that bends in the motion costs a chain split.
const MOTION_BEND_COST: f32 = super::limbs::MOTION_BEND;

/// Whether chain bones `i - 1` and `i` (towards their main children) are more than ~20°
/// apart in the joint positions `pos`; a zero-length bone bends nothing.
fn bends_at(ctx: &Ctx<'_>, pos: &[Vec3], chain: &[BoneId], i: usize) -> bool {
    let dir = |b: BoneId| match ctx.topo.main[b.index()] {
        Some(c) => (pos[c.index()] - pos[b.index()]).normalize_or_zero(),
        None => Vec3::ZERO,
    };
    let (x, y) = (dir(chain[i - 1]), dir(chain[i]));
    x != Vec3::ZERO && y != Vec3::ZERO && x.dot(y) < 0.94
}

/// Clavicle (or pelvis side) and helpers, upper and lower segment with their twist bones.
fn segment_roles(
    out: &mut Builder,
    chain: &[BoneId],
    split: &super::limbs::ChainSplit,
    is_leg: bool,
    conf: f32,
) {
    let e = split.extremity.min(chain.len());
    // Of several bones before the upper segment, the clavicle is the one that spans the
    // girdle: the longest, the first on near-ties (a scapula splitting it, a zero-length helper
    // before it at the spine's joint).
    let pre_len = |j: usize| out.lengths[chain[j].index()];
    let girdle = (0..split.upper).fold(None, |best: Option<usize>, j| match best {
        Some(g) if pre_len(j) <= 1.05 * pre_len(g) => Some(g),
        _ => Some(j),
    });
    for (j, &b) in chain.iter().enumerate().take(split.upper) {
        let role = match (Some(j) == girdle, is_leg) {
            (true, true) => Role::PelvisSide,
            (true, false) => Role::Clavicle,
            (false, _) => Role::Helper,
        };
        out.set(b, role, conf);
    }
    let (upper_role, lower_role) = if is_leg {
        (Role::UpperLeg, Role::LowerLeg)
    } else {
        (Role::UpperArm, Role::LowerArm)
    };
    out.set(chain[split.upper], upper_role, conf);
    for &b in &chain[split.upper + 1..split.lower] {
        out.set(b, Role::Twist, conf);
    }
    out.set(chain[split.lower], lower_role, conf);
    for &b in &chain[split.lower + 1..e] {
        out.set(b, Role::Twist, conf);
    }
}

/// The hand or foot (`rest[0]`) and what follows it: with a branch point (`fixed`, an index
/// into `rest`) the toes up to it and the digits beyond; else the extremity's own chain.
fn extremity_roles(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    member: LimbMember,
    rest: &[BoneId],
    fixed: Option<usize>,
    limb_section: usize,
    conf: f32,
) {
    let is_leg = member.kind == LimbKind::Leg;
    let (_, ext_kind) = section_kinds(member.kind);
    let ext_role = if is_leg { Role::Foot } else { Role::Hand };
    let (side, limb_index, ground) = (member.side, member.limb_index, member.ground);
    if let Some(f) = fixed {
        let hi = out.add_section(
            ext_kind,
            side,
            limb_index,
            rest[..=f].to_vec(),
            Some(limb_section),
            ground,
        );
        out.set(rest[0], ext_role, conf);
        for (k, &b) in rest[1..=f].iter().enumerate() {
            out.set(b, if k == 0 { Role::Toes } else { Role::Helper }, conf);
        }
        place_digits(ctx, out, member, rest[f], hi, conf);
    } else {
        let section = Some(limb_section);
        out.add_section(ext_kind, side, limb_index, rest.to_vec(), section, ground);
        out.set(rest[0], ext_role, conf);
        place_extremity_chain(ctx, out, rest, is_leg, conf);
    }
}

/// Roles of a hand or foot's digits below `hand` (section `hi`): toes and helpers for a foot
/// with a heel, else fingers named thumb first.
fn place_digits(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    member: LimbMember,
    hand: BoneId,
    hi: usize,
    conf: f32,
) {
    let LimbMember {
        side,
        kind,
        limb_index,
        ground,
        ..
    } = member;
    let is_leg = kind == LimbKind::Leg;
    let digits = digits_front_first(ctx, out, hand, (hi, side), conf);
    if is_leg && digits.len() <= 2 {
        place_toes(ctx, out, hand, &digits, (hi, side), conf);
        return;
    }
    let names_for: &[u8] = match digits.len() {
        1 => &[1],
        2 => &[0, 1],
        3 => &[0, 1, 2],
        4 => &[0, 1, 2, 4],
        _ => &[0, 1, 2, 3, 4],
    };
    for (j, &d) in digits.iter().enumerate() {
        let digit = names_for.get(j).copied().unwrap_or(j.min(255) as u8);
        let ch = ctx.topo.chain(d);
        out.add_section(
            SectionKind::Digit,
            side,
            limb_index,
            ch.clone(),
            Some(hi),
            ground,
        );
        for (k, &b) in ch.iter().enumerate() {
            out.set(
                b,
                Role::Finger {
                    digit,
                    joint: k.min(255) as u8,
                },
                conf * 0.8,
            );
        }
    }
}

/// The digits below `hand` (section `hi`, on `side`): its significant children, a zero-length
/// "palm" helper looked through (and made a helper), front-most first.
fn digits_front_first(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    hand: BoneId,
    (hi, side): (usize, Side),
    conf: f32,
) -> Vec<BoneId> {
    let mut digits = Vec::new();
    for c in ctx.significant_children(hand) {
        let coincident = (ctx.pos[c.index()] - ctx.pos[hand.index()]).length() < 1e-3 * ctx.size;
        if coincident && !ctx.is_leaf(c) {
            out.set(c, Role::Helper, conf);
            out.roles[c.index()].section = Some(hi as u16);
            out.roles[c.index()].side = side;
            digits.extend(ctx.significant_children(c));
        } else {
            digits.push(c);
        }
    }
    let fwd_of = |b: BoneId| {
        let ch = ctx.topo.chain(b);
        let c: Vec3 = ch.iter().map(|x| ctx.pos[x.index()]).sum::<Vec3>() / ch.len() as f32;
        c
    };
    let forward = ctx.forward;
    digits.sort_by(|&a, &b| fwd_of(b).dot(forward).total_cmp(&fwd_of(a).dot(forward)));
    digits
}

/// A foot with a heel: the main chain below `foot` carries the toes, the other digits are
/// helpers, all in the foot's section `hi` on `side`.
fn place_toes(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    foot: BoneId,
    digits: &[BoneId],
    (hi, side): (usize, Side),
    conf: f32,
) {
    let main = ctx.topo.main[foot.index()];
    for &d in digits {
        let ch = ctx.topo.chain(d);
        for (k, &b) in ch.iter().enumerate() {
            let role = match (Some(d) == main, k) {
                (true, 0) => Role::Toes,
                (true, _) => Role::ToeEnd,
                _ => Role::Helper,
            };
            out.set(b, role, conf * 0.8);
            out.roles[b.index()].section = Some(hi as u16);
            out.roles[b.index()].side = side;
        }
    }
}

/// Roles along an extremity without branches (`rest[0]` is the hand or foot): helpers for
/// coincident joints, then toes / one finger, ends.
fn place_extremity_chain(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    rest: &[BoneId],
    is_leg: bool,
    conf: f32,
) {
    let mut k = 0usize;
    for (i, &b) in rest.iter().enumerate().skip(1) {
        // A joint coincident with the previous one is a helper (CMU `LeftFingerBase`).
        if (ctx.pos[b.index()] - ctx.pos[rest[i - 1].index()]).length() < 1e-3 * ctx.size {
            out.set(b, Role::Helper, conf * 0.8);
            continue;
        }
        k += 1;
        // End sites (`lFoot_end`) are ends, not toes / fingers.
        if ctx.is_leaf(b) && ctx.names[b.index()].helper {
            let role = if is_leg { Role::ToeEnd } else { Role::Helper };
            out.set(b, role, conf * 0.8);
            continue;
        }
        let role = if is_leg {
            if k == 1 {
                Role::Toes
            } else {
                Role::ToeEnd
            }
        } else {
            Role::Finger {
                digit: 1,
                joint: (k - 1).min(255) as u8,
            }
        };
        out.set(b, role, conf * 0.8);
    }
}

/// Whether the branch at `chain[i]` is a forearm carrying several palm bones that all start
/// at one wrist point away from it (RobotExpressive-style `Palm1..3`): then the hand is the
/// palm on the chain, not the branching bone.
fn palms_below(ctx: &Ctx<'_>, chain: &[BoneId], i: usize) -> bool {
    let b = chain[i];
    let Some(&next) = chain.get(i + 1) else {
        return false;
    };
    let kids = ctx.significant_children(b);
    let at = ctx.pos[next.index()];
    let reach = (at - ctx.pos[b.index()]).length();
    let prev = (ctx.pos[b.index()] - ctx.pos[chain[i - 1].index()]).length();
    let together = kids
        .iter()
        .filter(|k| (ctx.pos[k.index()] - at).length() < 0.05 * reach)
        .count();
    // A forearm-long reach: a hand's own finger helpers (MakeHuman's `__Index1`) also start
    // at one point, but a hand's length from the wrist.
    together >= 2 && reach > 1.5 * prev
}
