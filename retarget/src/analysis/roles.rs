//! Roles and sections: the heart of the analysis (see the module diagram in `analysis`).

use glam::Vec3;

use super::limbs::fit_chain;
use super::names::{self, NameInfo};
use super::topology::Topology;
use super::vocabulary::{Role, SectionKind};
use super::{Analysis, BoneRole, Section, Side, SkeletonView};
use crate::skeleton::{BoneId, Skeleton};

/// One pair of limbs (or a lone side chain) hanging off a central bone.
struct Limb {
    parent: BoneId,
    /// Members: (chain root, side). Usually two, mirror images.
    members: Vec<(BoneId, Side)>,
    reach: f32,
    ground: bool,
    height: f32,
}

#[derive(Clone, Copy, PartialEq)]
enum LimbKind {
    Leg,
    Arm,
    Wing,
    Appendage,
}

struct Ctx<'a> {
    skel: &'a Skeleton,
    /// Per leaf: the detached bone continuing it (an IK foot at the end of a shin).
    extension: &'a [Option<BoneId>],
    /// Control bones beside the body (see `detached`).
    detached: &'a [bool],
    pos: &'a [Vec3],
    topo: &'a Topology,
    names: &'a [NameInfo],
    up: Vec3,
    forward: Vec3,
    size: f32,
}

impl Ctx<'_> {
    fn h(&self, b: BoneId) -> f32 {
        self.pos[b.index()].dot(self.up)
    }
    fn subtree(&self, b: BoneId) -> impl Iterator<Item = BoneId> {
        let s = b.index();
        (s..s + self.topo.size[s]).map(|i| BoneId(i as u16))
    }
    fn is_leaf(&self, b: BoneId) -> bool {
        self.skel.children(b).is_empty()
    }
    /// A leaf that only shadows its parent: coincident with it, lying on the parent's own
    /// segment (twist bones), or named as a helper.
    fn is_shadow(&self, b: BoneId) -> bool {
        if self.detached[b.index()] {
            return true;
        }
        if !self.is_leaf(b) {
            return false;
        }
        let Some(p) = self.skel.parent(b) else {
            return false;
        };
        let pp = self.pos[p.index()];
        let pb = self.pos[b.index()];
        if (pb - pp).length() < 1e-3 * self.size.max(1e-3) {
            return true;
        }
        if let Some(m) = self.topo.main[p.index()] {
            if m != b {
                let seg = self.pos[m.index()] - pp;
                let t = (pb - pp).dot(seg) / seg.length_squared().max(1e-12);
                let off = (pb - pp - seg * t).length();
                if (0.0..=1.0).contains(&t) && off < 0.01 * self.size {
                    return true;
                }
            }
        }
        self.names[b.index()].helper
    }
    /// The bone sits exactly on its parent's joint.
    fn is_coincident(&self, b: BoneId) -> bool {
        match self.skel.parent(b) {
            Some(p) => {
                (self.pos[b.index()] - self.pos[p.index()]).length() < 1e-3 * self.size.max(1e-3)
            }
            None => false,
        }
    }

    /// A twist bone: a leaf lying inside its parent's segment, or named so.
    fn is_twist(&self, b: BoneId) -> bool {
        let nm = &self.names[b.index()];
        if nm.tokens.iter().any(|t| t == "twist" || t == "roll") {
            return true;
        }
        let Some(p) = self.skel.parent(b) else {
            return false;
        };
        let Some(m) = self.topo.main[p.index()] else {
            return false;
        };
        if m == b || !self.is_leaf(b) {
            return false;
        }
        let pp = self.pos[p.index()];
        let seg = self.pos[m.index()] - pp;
        let d = self.pos[b.index()] - pp;
        let t = d.dot(seg) / seg.length_squared().max(1e-12);
        (0.05..=0.95).contains(&t) && (d - seg * t).length() < 0.01 * self.size
    }

    fn significant_children(&self, b: BoneId) -> Vec<BoneId> {
        self.skel
            .children(b)
            .iter()
            .copied()
            .filter(|&c| !self.is_shadow(c))
            .collect()
    }
}

/// A forward vote at least this large decides the sides against the names.
const GEOMETRY_CLEAR: f32 = 0.15;

pub(crate) fn analyze_impl(view: &SkeletonView<'_>) -> Analysis {
    let mut best: Option<(usize, Analysis)> = None;
    for posture in super::posture::candidates(view) {
        let a = analyze_posture(view, posture);
        let score = coherence(&a);
        if std::env::var("RIGCAST_DEBUG_LIMBS").is_ok() {
            eprintln!("candidate frame {:?} coherence {score} up {:?}", a.posture_frame, a.up);
        }
        if best.as_ref().is_none_or(|(s, _)| score > *s) {
            best = Some((score, a));
        }
    }
    match best {
        Some((_, a)) => a,
        None => analyze_posture(view, super::posture::choose(view)),
    }
}

/// How completely an analysis reads as a body: core roles found, and a humanoid counts extra.
fn coherence(a: &Analysis) -> usize {
    let core = a.roles.iter().filter(|r| r.role.is_core()).count();
    core + if a.humanoid { 10 } else { 0 }
}

fn analyze_posture(view: &SkeletonView<'_>, posture: super::posture::Posture) -> Analysis {
    let skel = view.skeleton;
    let n = skel.num_bones();
    let pos = posture.positions.clone();
    let used_pose = posture.used_pose;
    let names: Vec<NameInfo> = skel.names().iter().map(|s| names::normalize(s)).collect();
    if super::flat::is_flat(n, skel.roots().count()) {
        if let Some(a) = super::flat::analyze_flat_hand(skel, pos.clone(), names.clone()) {
            return a;
        }
    }
    let topo = Topology::build(skel, &pos);
    let body = super::detached::find(skel, &topo);
    let (lo, hi) = pos.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let size = (hi - lo).max_element().max(1e-3);

    // 1. Lateral axis from mirror twins (order-free shape hashes), up checked against legs.
    let (lateral, shallow_pair) = lateral_from_twins(skel, &topo, &pos, &body.detached);
    let mut up = Vec3::Y;
    if let Some((p, a, b)) = shallow_pair {
        let ends = |x: BoneId| pos[topo.chain(x).last().copied().unwrap_or(x).index()];
        let d = (ends(a) + ends(b)) * 0.5 - pos[p.index()];
        let down = d - lateral * d.dot(lateral);
        // The legs hang down and the body stands above its feet. When both say so the rig is
        // turned as a whole (Z-up or any other way) and comes out the same; a quadruped's
        // slanted hind legs alone (the body stands ahead of them) do not tilt it.
        let feet = (ends(a) + ends(b)) * 0.5;
        let body_n = body.detached.iter().filter(|d| !**d).count().max(1) as f32;
        let centroid = skel
            .bone_ids()
            .filter(|x| !body.detached[x.index()])
            .map(|x| pos[x.index()])
            .sum::<Vec3>()
            / body_n;
        let above = centroid - feet;
        let above = (above - lateral * above.dot(lateral)).normalize_or_zero();
        let legs_up = -down.normalize_or_zero();
        let agree = above.dot(legs_up) > 0.94;
        if down.length() > 0.05 * size {
            if agree && legs_up.dot(Vec3::Y) < 0.9 {
                // Legs and body agree: a rig turned as a whole.
                up = snap_axis((above + legs_up).normalize_or_zero());
            } else if legs_up.dot(Vec3::Y) < 0.5 {
                // Only the legs say so, and strongly (a Z-up quadruped).
                up = snap_axis(legs_up);
            }
        }
    }
    // Rigs are built along axes; a rest or frame that is not quite symmetric (one arm
    // forward) must not tilt the lateral axis into the body's length.
    let mut lat = snap_axis((lateral - up * lateral.dot(up)).normalize_or_zero());
    if lat == Vec3::ZERO {
        lat = if up.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
        lat = (lat - up * lat.dot(up)).normalize_or_zero();
    }
    if std::env::var("RIGCAST_DEBUG_LIMBS").is_ok() {
        eprintln!("lateral {lateral:?} lat {lat:?} up {up:?} shallow {shallow_pair:?}");
    }
    let extension = super::detached::extensions(skel, &pos, &body, up);
    let ctx = Ctx {
        skel,
        extension: &extension,
        detached: &body.detached,
        pos: &pos,
        topo: &topo,
        names: &names,
        up,
        forward: Vec3::Z,
        size,
    };
    let ground = pos.iter().map(|p| p.dot(up)).fold(f32::MAX, f32::min);
    let top = pos.iter().map(|p| p.dot(up)).fold(f32::MIN, f32::max);
    let hext = (top - ground).max(1e-3);

    // 2. Central tree and limbs hanging off it (sides still provisional: "+lat" / "-lat").
    let mut central = vec![false; n];
    let mut limbs: Vec<Limb> = Vec::new();
    let mut in_limb = vec![false; n];
    central[body.root.index()] = true;
    for i in 0..n {
        let p = BoneId(i as u16);
        if !central[i] {
            continue;
        }
        let mut plus = Vec::new();
        let mut minus = Vec::new();
        for &c in skel.children(p) {
            if body.detached[c.index()] {
                continue;
            }
            // Coincident / on-segment leaves (Rigify ORG- copies) never extend the centerline;
            // named end joints that stick out (`head_end`) do.
            if ctx.is_shadow(c) && !ctx.names[c.index()].helper && skel.children(p).len() > 1 {
                continue;
            }
            if ctx.is_shadow(c) && ctx.names[c.index()].helper && ctx.is_coincident(c) {
                continue;
            }
            let off = (topo.centroid[c.index()] - pos[i]).dot(lat);
            let spread = ctx
                .subtree(c)
                .map(|b| (pos[b.index()] - pos[i]).dot(lat).abs())
                .fold(0.0, f32::max);
            if off.abs() > 0.3 * spread && off.abs() > 0.005 * size {
                if off > 0.0 {
                    plus.push(c);
                } else {
                    minus.push(c);
                }
            } else {
                central[c.index()] = true;
            }
        }
        for (a, b) in pair_up(&ctx, &mut plus, &mut minus) {
            limbs.push(make_limb(
                &ctx,
                p,
                vec![(a, Side::Left), (b, Side::Right)],
                ground,
                hext,
            ));
        }
        for c in plus.into_iter().chain(minus) {
            let off = (topo.centroid[c.index()] - pos[i]).dot(lat);
            // Without a mirror twin, only a chain far to one side is a limb; a head that
            // sits a little off the midline continues the body.
            let extent = topo.reach[c.index()] + (pos[c.index()] - pos[i]).length();
            if off.abs() < 0.15 * extent {
                central[c.index()] = true;
                continue;
            }
            let s = if off > 0.0 { Side::Left } else { Side::Right };
            limbs.push(make_limb(&ctx, p, vec![(c, s)], ground, hext));
        }
    }
    for l in &limbs {
        for &(m, _) in &l.members {
            for b in ctx.subtree(m) {
                in_limb[b.index()] = true;
            }
        }
    }

    // 3. Forward from the body's own cues (feet, joint bends over the motion, thumbs, slope).
    let fwd0 = lat.cross(up).normalize_or_zero(); // = forward if +lat is the character's left
    let path0 = centerline(&ctx, &central);
    let pairs = |want_ground: bool| -> Vec<[BoneId; 2]> {
        limbs
            .iter()
            .filter(|l| l.members.len() == 2 && l.ground == want_ground && l.reach > 0.12 * size)
            .map(|l| [l.members[0].0, l.members[1].0])
            .collect()
    };
    let finput = super::forward::ForwardInput {
        skel,
        topo: &topo,
        pos: &pos,
        samples: &posture.samples,
        up,
        fwd0,
        size,
        ground,
        hext,
        legs: pairs(true),
        arms: pairs(false),
    };
    let vote = super::forward::vote(&finput, &path0);
    let cue = vote.total();
    let mut sign = if cue < 0.0 { -1.0 } else { 1.0 };
    // Names break ties and overrule geometry when they agree strongly.
    let (mut agree, mut disagree) = (0usize, 0usize);
    for l in &limbs {
        for &(m, s) in &l.members {
            for b in ctx.subtree(m) {
                match (names[b.index()].side, s) {
                    (Some(Side::Left), Side::Left) | (Some(Side::Right), Side::Right) => agree += 1,
                    (Some(Side::Left), Side::Right) | (Some(Side::Right), Side::Left) => {
                        disagree += 1
                    }
                    _ => {}
                }
            }
        }
    }
    // `s` above is relative to +lat; with sign = -1 the character's left is -lat.
    let name_sign = if agree + disagree >= 4 {
        if agree as f32 >= 0.75 * (agree + disagree) as f32 {
            Some(1.0)
        } else if disagree as f32 >= 0.75 * (agree + disagree) as f32 {
            Some(-1.0)
        } else {
            None
        }
    } else {
        None
    };
    // Geometry wins when it is clear; names only break a tie it cannot.
    let mut warnings = Vec::new();
    match name_sign {
        Some(s) if cue.abs() < GEOMETRY_CLEAR => sign = s,
        Some(s) if s != sign => warnings.push(format!(
            "names mark the sides the other way round from the geometry (forward vote {cue:.2}: \
             feet {:.2}, bends {:.2}, thumbs {:.2}); the geometry's sides are used",
            vote.feet, vote.bends, vote.thumbs
        )),
        _ => {}
    }
    let forward = fwd0 * sign;
    let left = up.cross(forward).normalize_or_zero();
    let ctx = Ctx { forward, ..ctx };
    if sign < 0.0 {
        for l in &mut limbs {
            for m in &mut l.members {
                m.1 = m.1.flipped();
            }
        }
    }

    // 4. Orient the centerline tail → head.
    let mut path = path0;
    if let (Some(&a), Some(&b)) = (path.first(), path.last()) {
        let score = |x: BoneId| pos[x.index()].dot(up) + 0.7 * pos[x.index()].dot(forward);
        if score(a) > score(b) {
            path.reverse();
        }
    }
    let k_of = |b: BoneId| path.iter().position(|&x| x == b);
    if std::env::var("RIGCAST_DEBUG_LIMBS").is_ok() {
        eprintln!("path {:?}", path.iter().map(|b| skel.name(*b)).collect::<Vec<_>>());
        for l in &limbs {
            eprintln!("limb at {} members {:?} reach {} ground {}", skel.name(l.parent), l.members.iter().map(|m| skel.name(m.0)).collect::<Vec<_>>(), l.reach, l.ground);
        }
    }

    // 5. Classify limbs.
    let mut kinds = vec![LimbKind::Appendage; limbs.len()];
    let big = |l: &Limb| l.reach > 0.12 * size && l.members.len() == 2;
    let leg_k = limbs
        .iter()
        .enumerate()
        .filter(|(_, l)| big(l) && l.ground)
        .filter_map(|(i, l)| k_of(l.parent).map(|k| (k, i)))
        .min_by_key(|&(k, _)| k);
    if let Some((lk, _)) = leg_k {
        // Several ground pairs on one central bone (a bug whose four legs hang from its root):
        // the rear-most pair are the legs, the ones ahead are front legs.
        let at_k: Vec<usize> = (0..limbs.len())
            .filter(|&i| big(&limbs[i]) && limbs[i].ground && k_of(limbs[i].parent) == Some(lk))
            .collect();
        let ahead = |i: usize| {
            let l = &limbs[i];
            l.members.iter().map(|m| pos[m.0.index()].dot(forward)).sum::<f32>() / 2.0
        };
        let rear = at_k
            .iter()
            .copied()
            .min_by(|&a, &b| ahead(a).total_cmp(&ahead(b)));
        for &i in &at_k {
            let clearly_ahead = rear.is_some_and(|r| ahead(i) - ahead(r) > 0.15 * size);
            kinds[i] = if clearly_ahead { LimbKind::Arm } else { LimbKind::Leg };
        }
    }
    // Arms are limbs of a size with the legs: eyes and ears on a long-faced rig are not.
    let leg_reach = limbs
        .iter()
        .zip(&kinds)
        .filter(|(_, k)| **k == LimbKind::Leg)
        .map(|(l, _)| l.reach)
        .fold(0.0f32, f32::max);
    let arm_cands: Vec<usize> = (0..limbs.len())
        .filter(|&i| kinds[i] != LimbKind::Leg && big(&limbs[i]) && k_of(limbs[i].parent).is_some())
        .filter(|&i| limbs[i].reach > 0.3 * leg_reach)
        .collect();
    // A quadruped's front legs reach the ground; smaller pairs ahead of them (ears, antlers,
    // horns) are head appendages, not a second pair of arms.
    let front_legs: Vec<usize> = arm_cands.iter().copied().filter(|&i| limbs[i].ground).collect();
    let arm_cands: Vec<usize> = arm_cands
        .into_iter()
        .filter(|&i| {
            limbs[i].ground
                || !front_legs.iter().any(|&f| {
                    k_of(limbs[i].parent) > k_of(limbs[f].parent)
                        && limbs[i].reach < 0.6 * limbs[f].reach
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
    let r = leg_k.map(|(k, _)| k).unwrap_or(0);
    let front = |kind: LimbKind| {
        (0..limbs.len())
            .filter(|&i| kinds[i] == kind)
            .filter_map(|i| k_of(limbs[i].parent))
            .max()
    };
    let f = front(LimbKind::Arm)
        .or(front(LimbKind::Wing))
        .unwrap_or(r)
        .max(r);
    // Limbs attached beyond the front-most limbs are head appendages (eyes, ears).
    for (i, l) in limbs.iter().enumerate() {
        if let Some(k) = k_of(l.parent) {
            if k > f && kinds[i] != LimbKind::Leg {
                kinds[i] = LimbKind::Appendage;
            }
        }
    }

    // 6. Sections and roles.
    let mut roles = vec![BoneRole::unknown(); n];
    let mut sections: Vec<Section> = Vec::new();
    let lengths = topo.length.clone();
    let mut add_section = |sections: &mut Vec<Section>,
                           roles: &mut Vec<BoneRole>,
                           kind: SectionKind,
                           side: Side,
                           limb: u8,
                           bones: Vec<BoneId>,
                           parent: Option<usize>,
                           ground: bool|
     -> usize {
        let total: f32 = bones.iter().map(|b| lengths[b.index()]).sum();
        let idx = sections.len();
        let mut acc = 0.0;
        let nb = bones.len().max(1) as f32;
        for (j, b) in bones.iter().enumerate() {
            let r = &mut roles[b.index()];
            r.section = Some(idx as u16);
            r.side = side;
            r.limb = limb;
            r.position = if total > 1e-6 {
                acc / total
            } else {
                j as f32 / nb
            };
            acc += lengths[b.index()];
        }
        sections.push(Section {
            kind,
            side,
            limb,
            bones,
            length: total,
            parent,
            ground,
        });
        idx
    };
    let set = |roles: &mut Vec<BoneRole>, b: BoneId, role: Role, conf: f32| {
        let r = &mut roles[b.index()];
        r.role = role;
        r.confidence = conf;
    };

    let mut spine_sec = None;
    let mut head_sec = None;
    if !path.is_empty() {
        let spine: Vec<BoneId> = path[r..=f.min(path.len() - 1)].to_vec();
        let si = add_section(
            &mut sections,
            &mut roles,
            SectionKind::Spine,
            Side::Center,
            0,
            spine.clone(),
            None,
            false,
        );
        spine_sec = Some(si);
        let conf = if leg_k.is_some() { 0.9 } else { 0.4 };
        // Legs on a branch of their own beside the spine (MakeHuman: `Root` carries the spine,
        // a child `Hips` only the legs): the pelvis is their common parent.
        let legs_beside = spine.len() > 2 && skel.parent(spine[0]) == Some(spine[1]);
        // A first "spine" segment that points down is still the pelvis (a hip bone hung below
        // the leg joint, RobotExpressive's `Body` → `Hips`).
        let drops = spine.len() > 3
            && (pos[spine[1].index()] - pos[spine[0].index()]).dot(up)
                < -0.01 * (pos[spine[2].index()] - pos[spine[1].index()]).length();
        let hips_at = usize::from(legs_beside || drops);
        if hips_at == 1 {
            set(&mut roles, spine[0], Role::Helper, conf);
        }
        set(&mut roles, spine[hips_at], Role::Hips, conf);
        let body = &spine[hips_at + 1..];
        for (j, &b) in body.iter().enumerate() {
            let role = if j == 0 {
                Role::Spine
            } else if j + 1 == body.len() {
                Role::Chest
            } else {
                Role::SpineMid
            };
            set(&mut roles, b, role, conf * 0.95);
        }
        if r > 0 {
            let tail: Vec<BoneId> = path[..r].iter().rev().copied().collect();
            add_section(
                &mut sections,
                &mut roles,
                SectionKind::Tail,
                Side::Center,
                0,
                tail.clone(),
                Some(si),
                false,
            );
            for (j, &b) in tail.iter().enumerate() {
                set(&mut roles, b, Role::Tail(j.min(255) as u8), 0.8);
            }
        }
        if f + 1 < path.len() {
            let head: Vec<BoneId> = path[f + 1..].to_vec();
            let hi = add_section(
                &mut sections,
                &mut roles,
                SectionKind::Head,
                Side::Center,
                0,
                head.clone(),
                Some(si),
                false,
            );
            head_sec = Some(hi);
            let head_idx = head_index(
                &ctx,
                &head,
                &central,
                &limbs,
                &kinds,
                leg_len(&ctx, &limbs, &kinds),
                uses_end_joints(&ctx, &limbs, &kinds, ground, hext),
            );
            for (j, &b) in head.iter().enumerate() {
                let role = if j < head_idx {
                    Role::Neck(j.min(255) as u8)
                } else if j == head_idx {
                    Role::Head
                } else {
                    Role::HeadEnd
                };
                set(&mut roles, b, role, 0.8);
            }
            // Central side branches at the head: the jaw (forward / down), else helpers.
            let hb = head[head_idx];
            for &c in skel.children(hb) {
                if central[c.index()] && !head.contains(&c) && !ctx.is_shadow(c) {
                    set(&mut roles, c, Role::Jaw, 0.6);
                    roles[c.index()].section = Some(hi as u16);
                }
            }
        }
    }
    let section_of_bone =
        |roles: &Vec<BoneRole>, b: BoneId| roles[b.index()].section.map(|s| s as usize);

    // Limb pair indices: upper / front-most first.
    let mut order: Vec<usize> = (0..limbs.len()).collect();
    order.sort_by(|&a, &b| {
        let ka = k_of(limbs[a].parent).unwrap_or(0);
        let kb = k_of(limbs[b].parent).unwrap_or(0);
        kb.cmp(&ka)
            .then(limbs[b].height.total_cmp(&limbs[a].height))
            .then(limbs[a].parent.cmp(&limbs[b].parent))
    });
    let mut counters = [0u8; 4];
    let mut humanoid_arms = 0;
    let mut humanoid_legs = 0;
    for &li in &order {
        let l = &limbs[li];
        let kind = kinds[li];
        let slot = kind as usize;
        let limb_index = counters[slot];
        counters[slot] = counters[slot].saturating_add(1);
        match kind {
            // Arms that reach the ground are a quadruped's front legs.
            LimbKind::Arm if l.ground => humanoid_arms += 10,
            LimbKind::Arm => humanoid_arms += 1,
            LimbKind::Leg => humanoid_legs += 1,
            _ => {}
        }
        let parent_sec = section_of_bone(&roles, l.parent);
        for &(m, side) in &l.members {
            if kind == LimbKind::Appendage {
                let bones: Vec<BoneId> = ctx.subtree(m).collect();
                add_section(
                    &mut sections,
                    &mut roles,
                    SectionKind::Appendage,
                    side,
                    0,
                    bones.clone(),
                    parent_sec,
                    false,
                );
                let at_head = head_sec.is_some()
                    && roles[l.parent.index()].role == Role::Head
                    && topo.size[m.index()] <= 3
                    && l.members.len() == 2
                    && !names[m.index()].helper;
                for &b in &bones {
                    set(&mut roles, b, Role::Appendage, 0.5);
                }
                if at_head {
                    set(&mut roles, m, Role::Eye, 0.6);
                }
                continue;
            }
            limb_roles(
                &ctx,
                m,
                side,
                kind,
                limb_index,
                l.ground,
                parent_sec,
                &mut sections,
                &mut roles,
                &mut add_section,
            );
        }
    }
    // Everything not placed yet: helpers, with the side of where they hang.
    for i in 0..n {
        if roles[i].role == Role::Unknown {
            let b = BoneId(i as u16);
            if let Some(p) = skel.parent(b) {
                let pr = roles[p.index()];
                roles[i].side = pr.side;
                roles[i].section = pr.section;
                roles[i].limb = pr.limb;
                roles[i].position = pr.position;
                roles[i].role = if ctx.is_twist(b) && in_limb[i] {
                    Role::Twist
                } else {
                    Role::Helper
                };
                roles[i].confidence = 0.3;
            } else {
                roles[i].role = Role::Helper;
                roles[i].confidence = 0.3;
            }
        }
    }
    attach_detached(&ctx, &body, &mut roles, &mut sections);
    let _ = spine_sec;
    let main_child = topo.main.clone();
    Analysis {
        up,
        forward,
        left,
        positions: pos,
        used_pose,
        posture_frame: posture.frame,
        size,
        lengths: topo.length.clone(),
        sections,
        roles,
        names,
        humanoid: humanoid_legs == 1 && humanoid_arms == 1,
        main_child,
        warnings,
    }
}

/// Assigns roles along one limb member (arm, leg or wing) and its extremity and digits.
#[allow(clippy::too_many_arguments)]
fn limb_roles(
    ctx: &Ctx<'_>,
    m: BoneId,
    side: Side,
    kind: LimbKind,
    limb_index: u8,
    ground: bool,
    parent_sec: Option<usize>,
    sections: &mut Vec<Section>,
    roles: &mut Vec<BoneRole>,
    add_section: &mut impl FnMut(
        &mut Vec<Section>,
        &mut Vec<BoneRole>,
        SectionKind,
        Side,
        u8,
        Vec<BoneId>,
        Option<usize>,
        bool,
    ) -> usize,
) {
    let chain = ctx.topo.chain(m);
    let lengths: Vec<f32> = chain.iter().map(|b| ctx.topo.length[b.index()]).collect();
    let dirs: Vec<Vec3> = chain
        .iter()
        .map(|b| match ctx.topo.main[b.index()] {
            Some(c) => (ctx.pos[c.index()] - ctx.pos[b.index()]).normalize_or_zero(),
            None => Vec3::ZERO,
        })
        .collect();
    let fixed = chain
        .iter()
        .enumerate()
        .skip(2)
        .find(|(_, &b)| ctx.significant_children(b).len() >= 2)
        .map(|(i, _)| i)
        .map(|i| if palms_below(ctx, &chain, i) { i + 1 } else { i });
    let is_leg = kind == LimbKind::Leg;
    let ratio = if is_leg { 1.05 } else { 1.12 };
    if std::env::var("RIGCAST_DEBUG_LIMBS").is_ok() {
        eprintln!("limb {:?} {:?} chain {:?} len {:?} fixed {:?}", kind as u8, side, chain.iter().map(|b| ctx.skel.name(*b)).collect::<Vec<_>>(), lengths, fixed);
    }
    let (limb_kind, ext_kind) = match kind {
        LimbKind::Leg => (SectionKind::Leg, SectionKind::Foot),
        LimbKind::Wing => (SectionKind::Wing, SectionKind::Hand),
        _ => (SectionKind::Arm, SectionKind::Hand),
    };
    // A leg's branch point may be the toes (claws) rather than the ankle: let the fit choose
    // the foot anywhere up to the branch.
    let fitted = match fixed {
        Some(f) if is_leg => fit_chain(&lengths[..=f], &dirs[..=f], None, ratio),
        _ => fit_chain(&lengths, &dirs, fixed, ratio),
    };
    let Some(split) = fitted else {
        let si = add_section(
            sections,
            roles,
            limb_kind,
            side,
            limb_index,
            chain.clone(),
            parent_sec,
            ground,
        );
        let _ = si;
        let role = if is_leg {
            Role::UpperLeg
        } else {
            Role::UpperArm
        };
        roles[chain[0].index()].role = role;
        roles[chain[0].index()].confidence = 0.3;
        return;
    };
    let conf = (0.95 * (-split.cost).exp()).clamp(0.2, 0.95);
    let e = split.extremity.min(chain.len());
    let limb_bones = chain[..e].to_vec();
    let li = add_section(
        sections, roles, limb_kind, side, limb_index, limb_bones, parent_sec, ground,
    );
    let set = |roles: &mut Vec<BoneRole>, b: BoneId, role: Role, c: f32| {
        roles[b.index()].role = role;
        roles[b.index()].confidence = c;
    };
    for (j, &b) in chain.iter().enumerate().take(split.upper) {
        let role = if j + 1 == split.upper {
            if is_leg {
                Role::PelvisSide
            } else {
                Role::Clavicle
            }
        } else {
            Role::Helper
        };
        set(roles, b, role, conf);
    }
    set(
        roles,
        chain[split.upper],
        if is_leg {
            Role::UpperLeg
        } else {
            Role::UpperArm
        },
        conf,
    );
    for &b in &chain[split.upper + 1..split.lower] {
        set(roles, b, Role::Twist, conf);
    }
    set(
        roles,
        chain[split.lower],
        if is_leg {
            Role::LowerLeg
        } else {
            Role::LowerArm
        },
        conf,
    );
    for &b in &chain[split.lower + 1..e] {
        set(roles, b, Role::Twist, conf);
    }
    if e >= chain.len() {
        return;
    }
    let hand = chain[e];
    let ext_role = if is_leg { Role::Foot } else { Role::Hand };
    if let Some(f) = fixed.filter(|&f| f >= e) {
        let hi = add_section(
            sections,
            roles,
            ext_kind,
            side,
            limb_index,
            chain[e..=f].to_vec(),
            Some(li),
            ground,
        );
        set(roles, hand, ext_role, conf);
        for (k, &b) in chain[e + 1..=f].iter().enumerate() {
            set(
                roles,
                b,
                if k == 0 { Role::Toes } else { Role::Helper },
                conf,
            );
        }
        let hand = chain[f];
        // Digits: significant children; a zero-length "palm" helper is looked through.
        let mut digits = Vec::new();
        for c in ctx.significant_children(hand) {
            let coincident =
                (ctx.pos[c.index()] - ctx.pos[hand.index()]).length() < 1e-3 * ctx.size;
            if coincident && !ctx.is_leaf(c) {
                set(roles, c, Role::Helper, conf);
                roles[c.index()].section = Some(hi as u16);
                roles[c.index()].side = side;
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
        let forward = forward_hint(roles, ctx);
        digits.sort_by(|&a, &b| fwd_of(b).dot(forward).total_cmp(&fwd_of(a).dot(forward)));
        if is_leg && digits.len() <= 2 {
            // A foot with a heel: the main chain carries the toes, the rest are helpers.
            let main = ctx.topo.main[hand.index()];
            for &d in &digits {
                let ch = ctx.topo.chain(d);
                for (k, &b) in ch.iter().enumerate() {
                    let role = match (Some(d) == main, k) {
                        (true, 0) => Role::Toes,
                        (true, _) => Role::ToeEnd,
                        _ => Role::Helper,
                    };
                    set(roles, b, role, conf * 0.8);
                    roles[b.index()].section = Some(hi as u16);
                    roles[b.index()].side = side;
                }
            }
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
            add_section(
                sections,
                roles,
                SectionKind::Digit,
                side,
                limb_index,
                ch.clone(),
                Some(hi),
                ground,
            );
            for (k, &b) in ch.iter().enumerate() {
                set(
                    roles,
                    b,
                    Role::Finger {
                        digit,
                        joint: k.min(255) as u8,
                    },
                    conf * 0.8,
                );
            }
        }
    } else {
        let rest = chain[e..].to_vec();
        add_section(
            sections,
            roles,
            ext_kind,
            side,
            limb_index,
            rest.clone(),
            Some(li),
            ground,
        );
        set(roles, hand, ext_role, conf);
        let mut k = 0usize;
        for (i, &b) in rest.iter().enumerate().skip(1) {
            // A joint coincident with the previous one is a helper (CMU `LeftFingerBase`).
            if (ctx.pos[b.index()] - ctx.pos[rest[i - 1].index()]).length() < 1e-3 * ctx.size {
                set(roles, b, Role::Helper, conf * 0.8);
                continue;
            }
            k += 1;
            // End sites (`lFoot_end`) are ends, not toes / fingers.
            if ctx.is_leaf(b) && ctx.names[b.index()].helper {
                let role = if is_leg { Role::ToeEnd } else { Role::Helper };
                set(roles, b, role, conf * 0.8);
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
            set(roles, b, role, conf * 0.8);
        }
    }
}

fn forward_hint(_roles: &[BoneRole], ctx: &Ctx<'_>) -> Vec3 {
    ctx.forward
}

/// Lateral axis estimate from mirror twins (sibling subtrees with equal shape hashes), and the
/// shallowest twin pair (parent, a, b), used to check the up axis against the legs.
fn lateral_from_twins(
    skel: &Skeleton,
    topo: &Topology,
    pos: &[Vec3],
    detached: &[bool],
) -> (Vec3, Option<(BoneId, BoneId, BoneId)>) {
    let size = topo.reach.iter().copied().fold(0.0f32, f32::max).max(1e-6);
    let mut pairs: Vec<(f32, Vec3, usize, BoneId, BoneId, BoneId)> = Vec::new();
    for p in skel.bone_ids() {
        let ch = skel.children(p);
        for (i, &a) in ch.iter().enumerate() {
            for &b in &ch[i + 1..] {
                if topo.hash[a.index()] != topo.hash[b.index()] {
                    continue;
                }
                // Exactly two siblings of this shape: a mirror pair, not a row of fingers.
                let same = ch
                    .iter()
                    .filter(|c| topo.hash[c.index()] == topo.hash[a.index()])
                    .count();
                if same != 2 {
                    continue;
                }
                if detached[a.index()] || detached[b.index()] {
                    continue;
                }
                // The twins' own joints are mirror images even when the rest pose is not
                // (one arm raised): use them, unless they coincide (CMU's hip helpers).
                let joints = pos[a.index()] - pos[b.index()];
                let v = if joints.length() > 0.02 * size {
                    joints
                } else {
                    topo.centroid[a.index()] - topo.centroid[b.index()]
                };
                let w = v.length() * topo.size[a.index()] as f32;
                if w > 0.0 {
                    pairs.push((w, v, skel.depth(p), p, a, b));
                }
            }
        }
    }
    pairs.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.3.cmp(&y.3)));
    let Some(first) = pairs.first() else {
        return (Vec3::X, None);
    };
    let reference = first.1;
    let mut sum = Vec3::ZERO;
    for (w, v, ..) in &pairs {
        let v = if v.dot(reference) < 0.0 { -*v } else { *v };
        sum += v.normalize_or_zero() * *w;
    }
    // Make the estimate independent of which twin came first: point it along +x/+y/+z majority.
    let mut lat = sum.normalize_or_zero();
    let m = lat.abs().max_element();
    let major = if lat.x.abs() == m {
        lat.x
    } else if lat.y.abs() == m {
        lat.y
    } else {
        lat.z
    };
    if major < 0.0 {
        lat = -lat;
    }
    // Shallowest pair (closest to the root), the heaviest among those.
    let shallow = pairs
        .iter()
        .min_by(|x, y| x.2.cmp(&y.2).then(y.0.total_cmp(&x.0)))
        .map(|t| (t.3, t.4, t.5));
    (lat, shallow)
}

/// Snaps a direction to the nearest coordinate axis when within ~25 degrees of it.
fn snap_axis(v: Vec3) -> Vec3 {
    let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    for a in axes {
        if v.dot(a) > 0.9 {
            return a;
        }
    }
    v
}

/// Pairs off-center children on the two sides as mirror images (similar reach and height,
/// equal shapes preferred). Unpaired ones stay in the lists.
fn pair_up(
    ctx: &Ctx<'_>,
    plus: &mut Vec<BoneId>,
    minus: &mut Vec<BoneId>,
) -> Vec<(BoneId, BoneId)> {
    let mut out = Vec::new();
    loop {
        let mut best: Option<(f32, usize, usize)> = None;
        for (i, &a) in plus.iter().enumerate() {
            for (j, &b) in minus.iter().enumerate() {
                let ra = ctx.topo.reach[a.index()] + 1e-3;
                let rb = ctx.topo.reach[b.index()] + 1e-3;
                let mut cost = (ra / rb).ln().abs();
                cost += (ctx.h(a) - ctx.h(b)).abs() / ctx.size * 4.0;
                cost += (ctx.topo.centroid[a.index()].dot(ctx.up)
                    - ctx.topo.centroid[b.index()].dot(ctx.up))
                .abs()
                    / ctx.size
                    * 4.0;
                if ctx.topo.hash[a.index()] != ctx.topo.hash[b.index()] {
                    cost += 0.5;
                }
                if cost < 1.5 && best.is_none_or(|(c, ..)| cost < c) {
                    best = Some((cost, i, j));
                }
            }
        }
        let Some((_, i, j)) = best else { break };
        out.push((plus.remove(i), minus.remove(j)));
    }
    out
}

fn make_limb(
    ctx: &Ctx<'_>,
    parent: BoneId,
    members: Vec<(BoneId, Side)>,
    ground: f32,
    hext: f32,
) -> Limb {
    let mut reach = 0.0;
    let mut low = f32::MAX;
    let mut height = 0.0;
    for &(m, _) in &members {
        reach +=
            ctx.topo.reach[m.index()] + (ctx.pos[m.index()] - ctx.pos[parent.index()]).length();
        height += ctx.h(m);
        let mut extra = 0.0f32;
        for b in ctx.subtree(m) {
            low = low.min(ctx.h(b));
            if let Some(x) = ctx.extension[b.index()] {
                low = low.min(ctx.h(x));
                // The detached foot is part of the limb's length too.
                extra = extra.max((ctx.pos[x.index()] - ctx.pos[b.index()]).length());
            }
        }
        reach += extra;
    }
    let k = members.len().max(1) as f32;
    Limb {
        parent,
        members,
        reach: reach / k,
        ground: low < ground + 0.2 * hext,
        height: height / k,
    }
}

/// Longest path (by length) through the central tree, as a bone list.
fn centerline(ctx: &Ctx<'_>, central: &[bool]) -> Vec<BoneId> {
    let n = central.len();
    let Some(root) = (0..n).find(|&i| central[i]) else {
        return Vec::new();
    };
    // Undirected adjacency among central bones.
    let neighbours = |b: usize| {
        let mut v: Vec<usize> = ctx
            .skel
            .children(BoneId(b as u16))
            .iter()
            .map(|c| c.index())
            .filter(|&c| central[c])
            .collect();
        if let Some(p) = ctx.skel.parent(BoneId(b as u16)) {
            if central[p.index()] {
                v.push(p.index());
            }
        }
        v
    };
    let far = |start: usize| -> (usize, Vec<Option<usize>>) {
        let mut dist = vec![f32::NAN; n];
        let mut prev = vec![None; n];
        dist[start] = 0.0;
        let mut stack = vec![start];
        while let Some(b) = stack.pop() {
            for c in neighbours(b) {
                if dist[c].is_nan() {
                    // A tiny per-edge term lets zero-length helpers still extend a path.
                    dist[c] = dist[b] + (ctx.pos[c] - ctx.pos[b]).length() + 1e-4 * ctx.size;
                    prev[c] = Some(b);
                    stack.push(c);
                }
            }
        }
        let mut best = start;
        for i in 0..n {
            if !dist[i].is_nan() && dist[i] > dist[best] + 1e-6 {
                best = i;
            }
        }
        (best, prev)
    };
    let (a, _) = far(root);
    let (b, prev) = far(a);
    let mut path = vec![BoneId(b as u16)];
    let mut cur = b;
    while let Some(p) = prev[cur] {
        path.push(BoneId(p as u16));
        cur = p;
    }
    path
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

/// Which bone of the head section is the head: where eyes or a jaw attach, else the last bone
/// unless it is an end joint (by name, or by being too long for a neck-to-head segment).
fn head_index(
    ctx: &Ctx<'_>,
    head: &[BoneId],
    central: &[bool],
    limbs: &[Limb],
    kinds: &[LimbKind],
    leg: Option<f32>,
    end_joints: Option<bool>,
) -> usize {
    for (j, &b) in head.iter().enumerate() {
        let has_pair = limbs
            .iter()
            .zip(kinds)
            .any(|(l, k)| l.parent == b && *k == LimbKind::Appendage && l.members.len() == 2);
        let has_jaw = ctx
            .skel
            .children(b)
            .iter()
            .any(|c| central[c.index()] && !head.contains(c) && !ctx.is_shadow(*c));
        if has_pair || has_jaw {
            return j;
        }
    }
    let last = head.len() - 1;
    if last == 0 || !ctx.is_leaf(head[last]) {
        return last;
    }
    let leaf = head[last];
    // A zero-length leaf only marks its parent's end (BVH End Site written at the joint).
    if (ctx.pos[leaf.index()] - ctx.pos[head[last - 1].index()]).length()
        < 1e-3 * ctx.size.max(1e-3)
    {
        return last - 1;
    }
    let nm = &ctx.names[leaf.index()];
    // End markers: `_end`/`End`/`Nub` (helper tokens) and the skull top (`head_top`,
    // `HeadTop_End`), even when the name also says "head".
    if nm.helper || nm.tokens.iter().any(|t| t == "top") {
        return last - 1;
    }
    // A bone named as the head is the head, however long the neck before it (the Fox) or
    // however big the head (cartoon robots).
    if nm.tokens.iter().any(|t| t == "head") {
        return last;
    }
    // Upright two-armed bodies: proportions tell the skull top from the skull base whatever
    // the names (anonymised skeletons included).
    if let Some(top) = leaf_is_skull_top(ctx, head, limbs, kinds) {
        return if top { last - 1 } else { last };
    }
    // Exporters that write end joints (BVH End Sites, Mixamo `_End`) write them everywhere:
    // if the toes have one, so has the head.
    if let Some(ends) = end_joints {
        return if ends { last - 1 } else { last };
    }
    let seg = (ctx.pos[head[last].index()] - ctx.pos[head[last - 1].index()]).length();
    let limit = leg.map(|l| 0.14 * l).unwrap_or(0.07 * ctx.size);
    if seg > limit {
        last - 1
    } else {
        last
    }
}

/// Whether the leaf ending an upright body's head chain is the top of the skull (an end
/// marker) rather than the head joint itself. Measured in torso lengths (shoulder line minus
/// hip height) above the shoulder line: the skull top sits ≈0.55–0.65 above, the skull base
/// (where head joints sit) ≈0.25–0.4. A skull-top leaf also ends a head-long segment (≥ 0.2
/// torso) from a joint that is itself above the shoulders. `None` when the body is not upright
/// (no arms above legs: quadrupeds, creatures) or the leaf is in the ambiguous band, so other
/// evidence decides.
fn leaf_is_skull_top(
    ctx: &Ctx<'_>,
    head: &[BoneId],
    limbs: &[Limb],
    kinds: &[LimbKind],
) -> Option<bool> {
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
    let leaf = head[n - 1];
    let below = head[n - 2];
    let r_leaf = (ctx.h(leaf) - shoulder) / torso;
    let r_below = (ctx.h(below) - shoulder) / torso;
    let seg = (ctx.pos[leaf.index()] - ctx.pos[below.index()]).length() / torso;
    if r_leaf >= 0.47 && r_below >= 0.1 && seg >= 0.2 {
        Some(true)
    } else if r_leaf <= 0.42 {
        Some(false)
    } else {
        None
    }
}

/// Detached bones that continue a leg ending without its foot (an IK foot under the root at
/// the end of a shin) take the foot's role; the other detached bones are controls, carriers
/// helpers.
fn attach_detached(
    ctx: &Ctx<'_>,
    body: &super::detached::BodyRoot,
    roles: &mut [BoneRole],
    sections: &mut Vec<Section>,
) {
    for l in ctx.skel.bone_ids() {
        let Some(b) = ctx.extension[l.index()] else { continue };
        let lr = roles[l.index()];
        // Only feet: IK foot targets carry the foot's motion; hand controls are handles.
        let (role, kind) = match lr.role {
            Role::LowerLeg => (Role::Foot, SectionKind::Foot),
            _ => continue,
        };
        let parent = lr.section.map(|s| s as usize);
        let ground = parent.is_some_and(|p| sections[p].ground);
        roles[b.index()] = BoneRole {
            role,
            section: Some(sections.len() as u16),
            position: 0.0,
            confidence: lr.confidence * 0.8,
            ..lr
        };
        sections.push(Section {
            kind,
            side: lr.side,
            limb: lr.limb,
            bones: vec![b],
            length: 0.0,
            parent,
            ground,
        });
    }
    for b in ctx.skel.bone_ids() {
        let attached = ctx.extension.contains(&Some(b)) && roles[b.index()].role == Role::Foot;
        if ctx.detached[b.index()] && !attached {
            roles[b.index()].role = Role::Control;
            roles[b.index()].confidence = 0.5;
        }
    }
    // Carriers (an armature node, UE's `root`) carry the root motion of some rigs: helpers,
    // which map onto the other rig's carrier.
    for &c in &body.carriers {
        roles[c.index()].role = Role::Helper;
        roles[c.index()].confidence = 0.5;
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
