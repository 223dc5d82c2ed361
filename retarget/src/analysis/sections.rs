//! The trunk and what hangs from it: which limb pairs are legs, arms, wings or head
//! appendages, and the spine / tail / head sections along the centerline with the neck, head
//! and head end told apart.

use super::context::{Builder, Ctx, Limb, LimbKind};
use super::vocabulary::{Role, SectionKind};
use super::Side;
use crate::skeleton::BoneId;

/// What the limbs are, and where the trunk's parts start on the centerline.
pub(super) struct Layout {
    /// Kind of each limb (same order as the limbs).
    pub(super) kinds: Vec<LimbKind>,
    /// Centerline index of the bone the (rear-most) legs hang from, if there are legs.
    pub(super) legs_at: Option<usize>,
    /// First spine bone on the centerline (the legs' bone, else 0).
    pub(super) r: usize,
    /// Last spine bone on the centerline (where the front-most arms hang).
    pub(super) f: usize,
}

/// Classifies the limbs: the rear-most ground pair are the legs (a second ground pair on the
/// same bone, clearly ahead, are front legs), limbs of a size with the legs are arms (or wings,
/// when much longer than the other arms), everything else and whatever hangs beyond the
/// front-most arms are appendages.
pub(super) fn classify(ctx: &Ctx<'_>, limbs: &[Limb], path: &[BoneId]) -> Layout {
    let mut kinds = vec![LimbKind::Appendage; limbs.len()];
    let legs_at = mark_legs(ctx, limbs, path, &mut kinds);
    mark_arms(ctx, limbs, path, legs_at, &mut kinds);
    let r = legs_at.unwrap_or(0);
    let front = |kind: LimbKind| {
        (0..limbs.len())
            .filter(|&i| kinds[i] == kind)
            .filter_map(|i| centerline_index(path, limbs[i].parent))
            .max()
    };
    let f = front(LimbKind::Arm)
        .or(front(LimbKind::Wing))
        .unwrap_or(r)
        .max(r);
    // Limbs attached beyond the front-most limbs are head appendages (eyes, ears).
    for (i, l) in limbs.iter().enumerate() {
        if let Some(k) = centerline_index(path, l.parent) {
            if k > f && kinds[i] != LimbKind::Leg {
                kinds[i] = LimbKind::Appendage;
            }
        }
    }
    Layout {
        kinds,
        legs_at,
        r,
        f,
    }
}

/// Where bone `b` is on the centerline `path`.
fn centerline_index(path: &[BoneId], b: BoneId) -> Option<usize> {
    path.iter().position(|&x| x == b)
}

/// A limb pair big enough to be a leg, arm or wing: two members reaching over an eighth of
/// the skeleton's size.
fn is_big(ctx: &Ctx<'_>, l: &Limb) -> bool {
    l.reach > 0.12 * ctx.size && l.members.len() == 2
}

/// Marks the legs in `kinds`: the ground pairs on the rear-most central bone that carries one.
/// Several ground pairs on one central bone (a bug whose four legs hang from its root): the
/// rear-most pair are the legs, the ones clearly ahead are front legs (arms). Returns the
/// legs' centerline index.
fn mark_legs(
    ctx: &Ctx<'_>,
    limbs: &[Limb],
    path: &[BoneId],
    kinds: &mut [LimbKind],
) -> Option<usize> {
    let on_ground = |i: usize| is_big(ctx, &limbs[i]) && limbs[i].ground;
    let lk = (0..limbs.len())
        .filter(|&i| on_ground(i))
        .filter_map(|i| centerline_index(path, limbs[i].parent))
        .min()?;
    let at_k: Vec<usize> = (0..limbs.len())
        .filter(|&i| on_ground(i) && centerline_index(path, limbs[i].parent) == Some(lk))
        .collect();
    let ahead = |i: usize| {
        let l = &limbs[i];
        l.members
            .iter()
            .map(|m| ctx.pos[m.0.index()].dot(ctx.forward))
            .sum::<f32>()
            / 2.0
    };
    let rear = at_k
        .iter()
        .copied()
        .min_by(|&a, &b| ahead(a).total_cmp(&ahead(b)));
    for &i in &at_k {
        let clearly_ahead = rear.is_some_and(|r| ahead(i) - ahead(r) > 0.15 * ctx.size);
        kinds[i] = if clearly_ahead {
            LimbKind::Arm
        } else {
            LimbKind::Leg
        };
    }
    Some(lk)
}

/// Marks the arms and wings in `kinds` (the legs already marked, hanging at `legs_k`): limbs
/// of a size with the legs, not hanging from the head; of several arm pairs one much longer
/// than the others is a wing pair.
fn mark_arms(
    ctx: &Ctx<'_>,
    limbs: &[Limb],
    path: &[BoneId],
    legs_k: Option<usize>,
    kinds: &mut [LimbKind],
) {
    let k_of = |b: BoneId| centerline_index(path, b);
    // Arms are limbs of a size with the legs: eyes and ears on a long-faced rig are not.
    let leg_reach = limbs
        .iter()
        .zip(kinds.iter())
        .filter(|(_, k)| **k == LimbKind::Leg)
        .map(|(l, _)| l.reach)
        .fold(0.0f32, f32::max);
    let arm_cands: Vec<usize> = (0..limbs.len())
        .filter(|&i| {
            kinds[i] != LimbKind::Leg && is_big(ctx, &limbs[i]) && k_of(limbs[i].parent).is_some()
        })
        .filter(|&i| limbs[i].reach > 0.3 * leg_reach)
        .collect();
    // Arms hang from the upper torso, not from the head: of two pairs, the one attached further
    // along the body is a head appendage (ribbons, hair, ears, antlers) when it reaches clearly
    // less for the body below it than the other does. An arm reaches about twice the torso
    // under it; hair on a head reaches about the torso under it, though it may be as long as a
    // short arm. Ground limbs are legs whatever their size.
    let for_body = |i: usize| reach_for_body(ctx, path, legs_k, &limbs[i]);
    let arm_cands: Vec<usize> = arm_cands
        .iter()
        .copied()
        .filter(|&i| {
            limbs[i].ground
                || !arm_cands.iter().any(|&f| {
                    k_of(limbs[i].parent) > k_of(limbs[f].parent) && for_body(i) < 0.6 * for_body(f)
                })
        })
        .collect();
    let min_reach = arm_cands
        .iter()
        .map(|&i| limbs[i].reach)
        .fold(f32::MAX, f32::min);
    for &i in &arm_cands {
        kinds[i] = if arm_cands.len() > 1 && limbs[i].reach > 1.6 * min_reach {
            LimbKind::Wing
        } else {
            LimbKind::Arm
        };
    }
}

/// How far a limb pair reaches for the body below it: its reach over the centerline's length
/// from the legs' bone (else the centerline's start) to the bone it hangs from, at least a
/// twentieth of the skeleton's size (arms hanging from the legs' own bone).
fn reach_for_body(ctx: &Ctx<'_>, path: &[BoneId], legs_k: Option<usize>, l: &Limb) -> f32 {
    let k = path.iter().position(|&x| x == l.parent).unwrap_or(0);
    let r = legs_k.unwrap_or(0);
    let (a, b) = (k.min(r), k.max(r));
    let body: f32 = path[a..=b]
        .windows(2)
        .map(|w| (ctx.pos[w[1].index()] - ctx.pos[w[0].index()]).length())
        .sum();
    l.reach / body.max(0.05 * ctx.size)
}

/// Spine, tail and head sections along the centerline, with their roles. Returns the head
/// section's index, if there is a head.
pub(super) fn trunk(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    path: &[BoneId],
    layout: &Layout,
    central: &[bool],
    limbs: &[Limb],
    ends: (f32, f32),
) -> Option<usize> {
    if path.is_empty() {
        return None;
    }
    let si = spine_section(ctx, out, path, layout);
    if layout.r > 0 {
        let tail: Vec<BoneId> = path[..layout.r].iter().rev().copied().collect();
        out.add_section(
            SectionKind::Tail,
            Side::Center,
            0,
            tail.clone(),
            Some(si),
            false,
        );
        for (j, &b) in tail.iter().enumerate() {
            out.set(b, Role::Tail(j.min(255) as u8), 0.8);
        }
    }
    if layout.f + 1 >= path.len() {
        return None;
    }
    let head: Vec<BoneId> = path[layout.f + 1..].to_vec();
    let hi = out.add_section(
        SectionKind::Head,
        Side::Center,
        0,
        head.clone(),
        Some(si),
        false,
    );
    head_roles(ctx, out, (&head, hi), layout, central, limbs, ends);
    Some(hi)
}

/// The spine section, from the legs' bone to where the front-most arms hang: helpers below
/// the hips, the hips, then spine, spine middles and chest. Returns its index.
fn spine_section(ctx: &Ctx<'_>, out: &mut Builder, path: &[BoneId], layout: &Layout) -> usize {
    let spine: Vec<BoneId> = path[layout.r..=layout.f.min(path.len() - 1)].to_vec();
    let si = out.add_section(
        SectionKind::Spine,
        Side::Center,
        0,
        spine.clone(),
        None,
        false,
    );
    let conf = if layout.legs_at.is_some() { 0.9 } else { 0.4 };
    let hips_at = hips_index(ctx, &spine);
    for &b in &spine[..hips_at] {
        out.set(b, Role::Helper, conf);
    }
    out.set(spine[hips_at], Role::Hips, conf);
    let body = &spine[hips_at + 1..];
    for (j, &b) in body.iter().enumerate() {
        let role = if j == 0 {
            Role::Spine
        } else if j + 1 == body.len() {
            Role::Chest
        } else {
            Role::SpineMid
        };
        out.set(b, role, conf * 0.95);
    }
    si
}

/// The head section's roles (section `hi`): neck bones, the head, what is beyond it, and the
/// jaw among the head's central side branches; a doubt when the head bone was a near call.
fn head_roles(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    (head, hi): (&[BoneId], usize),
    layout: &Layout,
    central: &[bool],
    limbs: &[Limb],
    (ground, hext): (f32, f32),
) {
    let (head_idx, doubt) = head_index(
        ctx,
        head,
        central,
        limbs,
        &layout.kinds,
        leg_len(ctx, limbs, &layout.kinds),
        uses_end_joints(ctx, limbs, &layout.kinds, ground, hext),
    );
    if let Some((strength, bones, alone)) = doubt {
        let on = if alone {
            "the skull-top proportion alone (no names, motion or end joints)"
        } else {
            "proportions and end-joint conventions that nearly read it one bone off"
        };
        out.doubts.push(super::Doubt {
            reason: format!("which bone is the head rests on {on} ({strength:.2})"),
            strength,
            bones,
        });
    }
    for (j, &b) in head.iter().enumerate() {
        let role = if j < head_idx {
            Role::Neck(j.min(255) as u8)
        } else if j == head_idx {
            Role::Head
        } else {
            Role::HeadEnd
        };
        out.set(b, role, 0.8);
    }
    // Central side branches at the head: the jaw (forward / down), else helpers.
    let hb = head[head_idx];
    for &c in ctx.skel.children(hb) {
        if central[c.index()] && !head.contains(&c) && !ctx.is_shadow(c) {
            out.set(c, Role::Jaw, 0.6);
            out.roles[c.index()].section = Some(hi as u16);
        }
    }
}

/// Which bone of the spine section (from the legs' bone up) is the hips: the first, unless
/// legs hang on a branch of their own beside the spine (MakeHuman: `Root` carries the spine, a
/// child `Hips` only the legs: the pelvis is their common parent), or the first spine segment
/// points down (a hip bone hung below the leg joint, RobotExpressive's `Body` → `Hips`: still
/// the pelvis). Bones stacked on one joint count as one there, the last of them the hips (a
/// zero-length pelvis helper above the hip bone, whose own zero-length segment pointed
/// nowhere and made the helper the hips).
fn hips_index(ctx: &Ctx<'_>, spine: &[BoneId]) -> usize {
    if spine.len() > 2 && ctx.skel.parent(spine[0]) == Some(spine[1]) {
        return 1;
    }
    let mut h = 1;
    while h + 2 < spine.len() && ctx.is_coincident(spine[h + 1]) {
        h += 1;
    }
    let at = |k: usize| ctx.pos[spine[k].index()];
    let drops =
        spine.len() > h + 2 && (at(h) - at(0)).dot(ctx.up) < -0.01 * (at(h + 1) - at(h)).length();
    if drops {
        h
    } else {
        0
    }
}

/// Mean leg length (thigh to ground) of the legs, for head proportions.
fn leg_len(ctx: &Ctx<'_>, limbs: &[Limb], kinds: &[LimbKind]) -> Option<f32> {
    limbs
        .iter()
        .zip(kinds)
        .find(|(_, k)| **k == LimbKind::Leg)
        .map(|(l, _)| l.reach)
        .filter(|r| *r > 1e-4 * ctx.size)
}

/// Whether the legs end in end joints: a leaf lying level with its parent on the ground (a
/// toe tip after the toe base), as opposed to a toe joint below the ankle. `None` without legs.
fn uses_end_joints(
    ctx: &Ctx<'_>,
    limbs: &[Limb],
    kinds: &[LimbKind],
    ground: f32,
    hext: f32,
) -> Option<bool> {
    let mut seen = None;
    for (l, k) in limbs.iter().zip(kinds) {
        if *k != LimbKind::Leg {
            continue;
        }
        for &(m, _) in &l.members {
            let chain = ctx.topo.chain(m);
            if chain.len() < 3 {
                continue;
            }
            let leaf = chain[chain.len() - 1];
            let parent = chain[chain.len() - 2];
            let level = (ctx.h(leaf) - ctx.h(parent)).abs() < 0.02 * hext;
            let low = ctx.h(parent) < ground + 0.05 * hext;
            let ends = level && low;
            seen = Some(seen.unwrap_or(false) || ends);
        }
    }
    seen
}

/// A head reading's doubt: its strength, the bones the other reading reads otherwise, and
/// whether the skull-top proportion alone decided it.
type HeadDoubt = (f32, Vec<BoneId>, bool);

/// Which bone of the head section is the head: where eyes or a jaw attach, else the last bone
/// unless it is an end joint (by name, or by being too long for a neck-to-head segment). With
/// the index, the doubt of a reading from proportions and conventions alone.
fn head_index(
    ctx: &Ctx<'_>,
    head: &[BoneId],
    central: &[bool],
    limbs: &[Limb],
    kinds: &[LimbKind],
    leg: Option<f32>,
    end_joints: Option<bool>,
) -> (usize, Option<HeadDoubt>) {
    if let Some(j) = where_the_face_hangs(ctx, head, central, limbs, kinds) {
        return (j, None);
    }
    let last = head.len() - 1;
    if last == 0 || !ctx.is_leaf(head[last]) {
        return (last, None);
    }
    if let Some(k) = head_by_leaf(ctx, head) {
        return (k, None);
    }
    // Exporters that write end joints (BVH End Sites, Mixamo `_End`) write them everywhere:
    // if the toes have one, so has the head.
    let ends = end_joints.map(|e| if e { END_JOINTS } else { -END_JOINTS });
    if let Some(skull) = skull_heights(ctx, head, limbs, kinds) {
        return head_by_skull(ctx, head, &skull, ends);
    }
    if let Some(e) = ends {
        return (if e > 0.0 { last - 1 } else { last }, None);
    }
    let seg = (ctx.pos[head[last].index()] - ctx.pos[head[last - 1].index()]).length();
    let limit = leg.map(|l| 0.14 * l).unwrap_or(0.07 * ctx.size);
    if seg > limit {
        (last - 1, None)
    } else {
        (last, None)
    }
}

/// The first head-section bone that a pair of appendages (eyes, ears) or a jaw hangs from.
fn where_the_face_hangs(
    ctx: &Ctx<'_>,
    head: &[BoneId],
    central: &[bool],
    limbs: &[Limb],
    kinds: &[LimbKind],
) -> Option<usize> {
    head.iter().position(|&b| {
        let has_pair = limbs
            .iter()
            .zip(kinds)
            .any(|(l, k)| l.parent == b && *k == LimbKind::Appendage && l.members.len() == 2);
        let has_jaw = ctx
            .skel
            .children(b)
            .iter()
            .any(|c| central[c.index()] && !head.contains(c) && !ctx.is_shadow(*c));
        has_pair || has_jaw
    })
}

/// What the head section's leaf (it has two bones or more) says of itself: an end marker
/// (zero length, an end or skull-top name: the head is the bone before), named as the head,
/// or, in motion, the last bone that rotates. `None` when it says nothing.
fn head_by_leaf(ctx: &Ctx<'_>, head: &[BoneId]) -> Option<usize> {
    let last = head.len() - 1;
    let leaf = head[last];
    // A zero-length leaf only marks its parent's end (BVH End Site written at the joint).
    if (ctx.pos[leaf.index()] - ctx.pos[head[last - 1].index()]).length()
        < 1e-3 * ctx.size.max(1e-3)
    {
        return Some(last - 1);
    }
    let nm = &ctx.names[leaf.index()];
    // End markers: `_end`/`End`/`Nub` (helper tokens) and the skull top (`head_top`,
    // `HeadTop_End`), even when the name also says "head".
    if nm.helper || nm.tokens.iter().any(|t| t == "top") {
        return Some(last - 1);
    }
    // A bone named as the head is the head, however long the neck before it (the Fox) or
    // however big the head (cartoon robots).
    if nm.tokens.iter().any(|t| t == "head") {
        return Some(last);
    }
    // Motion: the head is the last bone of the chain that rotates; bones after it that never
    // do are end markers (a BVH End Site, an exporter's `HeadTop_End` joint). Measured, so it
    // outweighs proportions, which cartoon heads and robots break.
    let moving = ctx.moving?;
    head.iter().rposition(|b| moving[b.index()])
}

/// Upright two-armed bodies: proportions tell the skull top from the skull base whatever the
/// names (anonymised skeletons included). Both they and the end-joint convention (`ends`) are
/// evidence for the leaf being an end marker (positive) or the head; their sum decides, and
/// how close it came is the doubt.
fn head_by_skull(
    ctx: &Ctx<'_>,
    head: &[BoneId],
    skull: &Skull,
    ends: Option<f32>,
) -> (usize, Option<HeadDoubt>) {
    let last = head.len() - 1;
    let total = skull.leaf_evidence + ends.unwrap_or(0.0);
    let k = if total > 0.0 {
        // Every bone above the skull top before the leaf ends the head too (a cartoon's
        // `HeadTop_End` with its own end joint): the head is the last one below it.
        let below = head[..last]
            .iter()
            .rposition(|b| skull.r(ctx, *b) < SKULL_TOP);
        below.filter(|&k| k + 1 < last && k > 0).unwrap_or(last - 1)
    } else {
        last
    };
    // The skull-top proportion alone is no reading to trust: on the zoo's rigs a head leaf and
    // a skull-top leaf overlap (0.39-0.67 torso up, a robot's big head, a small skull over low
    // arms), so with nothing to cross it the head is a guess a person checks.
    let alone = ends.is_none();
    let floor = if alone { PROPORTIONS_ALONE } else { 0.0 };
    let strength = (-total.abs()).exp().max(floor);
    let bones = head[k.saturating_sub(1)..].to_vec();
    (
        k,
        (strength > DOUBT_FLOOR).then_some((strength, bones, alone)),
    )
}

/// What the end-joint convention weighs as evidence that the head chain's leaf is an end
/// marker, against the skull-top proportion (whose unit is [`SKULL_SCALE`]).
const END_JOINTS: f32 = 1.0;

/// The doubt over a head read from the skull-top proportion alone: as strong as the mapper's
/// confidence flags (`DOUBT_FLAG`).
const PROPORTIONS_ALONE: f32 = 0.9;

/// Torso lengths above the shoulder line halfway between where head joints sit (the skull
/// base, ≈0.25–0.4) and where the skull top does (≈0.55–0.65).
const SKULL_TOP: f32 = 0.445;

/// Torso lengths per unit of evidence in the skull-top proportion.
const SKULL_SCALE: f32 = 0.1;

/// Doubts weaker than this are not worth carrying.
const DOUBT_FLOOR: f32 = 0.05;

/// An upright body's head chain measured in torso lengths (shoulder line minus hip height)
/// above the shoulder line, and the evidence its leaf gives of being the skull top.
struct Skull {
    shoulder: f32,
    torso: f32,
    /// Positive: the leaf is the skull top (an end marker); negative: it is the head joint.
    leaf_evidence: f32,
}

impl Skull {
    fn r(&self, ctx: &Ctx<'_>, b: BoneId) -> f32 {
        (ctx.h(b) - self.shoulder) / self.torso
    }
}

/// The skull-top evidence of the leaf ending an upright body's head chain: how far it sits
/// above or below [`SKULL_TOP`], in [`SKULL_SCALE`] units (within ±3). A skull-top leaf also
/// ends a head-long segment (≥ 0.2 torso) from a joint that is itself above the shoulders;
/// otherwise a high leaf is no evidence either way. `None` when the body is not upright (no
/// arms above legs: quadrupeds, creatures).
fn skull_heights(
    ctx: &Ctx<'_>,
    head: &[BoneId],
    limbs: &[Limb],
    kinds: &[LimbKind],
) -> Option<Skull> {
    let n = head.len();
    if n < 2 {
        return None;
    }
    // Shoulder line: the highest of each arm chain's first joints, because a clavicle may start
    // low on the chest (CMU's zero-length `LeftShoulder`) while the upper arm sits on top.
    let mut shoulder: Option<f32> = None;
    let mut hip: Option<f32> = None;
    for (l, k) in limbs.iter().zip(kinds) {
        match k {
            LimbKind::Arm => {
                for &(m, _) in &l.members {
                    let top = ctx
                        .topo
                        .chain(m)
                        .iter()
                        .take(3)
                        .map(|b| ctx.h(*b))
                        .fold(f32::MIN, f32::max);
                    shoulder = Some(shoulder.map_or(top, |s| s.max(top)));
                }
            }
            LimbKind::Leg => hip = Some(hip.map_or(l.height, |h| h.max(l.height))),
            _ => {}
        }
    }
    let (shoulder, hip) = (shoulder?, hip?);
    let torso = shoulder - hip;
    if torso < 0.1 * ctx.size {
        return None;
    }
    let mut skull = Skull {
        shoulder,
        torso,
        leaf_evidence: 0.0,
    };
    let (leaf, below) = (head[n - 1], head[n - 2]);
    let r_leaf = skull.r(ctx, leaf);
    let seg = (ctx.pos[leaf.index()] - ctx.pos[below.index()]).length() / torso;
    let ends_a_skull = skull.r(ctx, below) >= 0.1 && seg >= 0.2;
    let e = ((r_leaf - SKULL_TOP) / SKULL_SCALE).clamp(-3.0, 3.0);
    skull.leaf_evidence = if e > 0.0 && !ends_a_skull { 0.0 } else { e };
    Some(skull)
}

#[cfg(test)]
mod tests {
    use crate::analysis::{analyze, SectionKind, SkeletonView};

    #[test]
    fn quadruped_legs_front_legs_and_tail() {
        let e = crate::corpus::get("horse").expect("corpus");
        let a = analyze(&SkeletonView::rest(&e.skeleton));
        let count = |k: SectionKind, ground: bool| {
            a.sections
                .iter()
                .filter(|s| s.kind == k && s.ground == ground)
                .count()
        };
        assert_eq!(count(SectionKind::Leg, true), 2);
        assert_eq!(
            count(SectionKind::Arm, true),
            2,
            "front legs are ground-reaching arms"
        );
        assert_eq!(count(SectionKind::Tail, false), 1);
        assert_eq!(count(SectionKind::Head, false), 1);
        assert!(!a.humanoid);
    }
}
