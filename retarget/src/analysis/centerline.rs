//! The centerline and the limbs hanging off it. Starting from the body root, a child whose
//! subtree lies clearly to one side (along the lateral axis) starts a limb, the others continue
//! the central tree; mirror-image limbs on the two sides pair up. The centerline is the central
//! tree's longest path, oriented tail → head.

use std::collections::HashMap;

use glam::Vec3;

use super::context::{Ctx, Limb};
use super::Side;
use crate::skeleton::BoneId;

/// The central tree (per bone) and the limbs hanging off it. Sides are provisional: `Left`
/// means "on the `+lat` side" until the forward axis is known.
pub(super) fn central_and_limbs(
    ctx: &Ctx<'_>,
    root: BoneId,
    lat: Vec3,
    ground: f32,
    hext: f32,
) -> (Vec<bool>, Vec<Limb>) {
    let n = ctx.skel.num_bones();
    let mut central = vec![false; n];
    let mut limbs: Vec<Limb> = Vec::new();
    central[root.index()] = true;
    for i in 0..n {
        let p = BoneId(i as u16);
        if !central[i] {
            continue;
        }
        let (mut plus, mut minus, considered) = split_children(ctx, p, lat, &mut central);
        for (a, b) in pair_up(ctx, &mut plus, &mut minus) {
            limbs.push(make_limb(
                ctx,
                p,
                vec![(a, Side::Left), (b, Side::Right)],
                ground,
                hext,
            ));
        }
        for c in plus.into_iter().chain(minus) {
            match lone_limb_side(ctx, p, c, lat, considered) {
                Some(s) => limbs.push(make_limb(ctx, p, vec![(c, s)], ground, hext)),
                None => central[c.index()] = true,
            }
        }
    }
    stand_together(&mut limbs, hext);
    (central, limbs)
}

/// `p`'s children (not detached, not shadow copies) that lie to one side: those on `+lat`,
/// those on `-lat`, and how many children were considered. The others continue the central
/// tree and are marked in `central`.
fn split_children(
    ctx: &Ctx<'_>,
    p: BoneId,
    lat: Vec3,
    central: &mut [bool],
) -> (Vec<BoneId>, Vec<BoneId>, usize) {
    let (skel, pos, topo, i) = (ctx.skel, ctx.pos, ctx.topo, p.index());
    let mut plus = Vec::new();
    let mut minus = Vec::new();
    let twins = twins_of(ctx, p);
    let mut considered = 0;
    for &c in skel.children(p) {
        if ctx.detached[c.index()] {
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
        considered += 1;
        let off = (topo.centroid[c.index()] - pos[i]).dot(lat);
        let spread = ctx
            .subtree(c)
            .map(|b| (pos[b.index()] - pos[i]).dot(lat).abs())
            .fold(0.0, f32::max);
        let side = twin_offset(ctx, p, c, &twins, lat)
            .or_else(|| (off.abs() > 0.3 * spread && off.abs() > 0.005 * ctx.size).then_some(off));
        match side {
            Some(off) if off > 0.0 => plus.push(c),
            Some(_) => minus.push(c),
            None => central[c.index()] = true,
        }
    }
    (plus, minus, considered)
}

/// The side of an unpaired child `c` of central bone `p` that is a limb, or `None` where it
/// continues the body. Without a mirror twin, only a chain far to one side is a limb; a head
/// that sits a little off the midline continues the body, and so does a central bone's only
/// child that goes on (a head tilted over its neck, its end joint on it): a limb hangs beside a
/// body that continues. A lone end joint is left as it was.
fn lone_limb_side(
    ctx: &Ctx<'_>,
    p: BoneId,
    c: BoneId,
    lat: Vec3,
    considered: usize,
) -> Option<Side> {
    let (pos, topo, i) = (ctx.pos, ctx.topo, p.index());
    let off = (topo.centroid[c.index()] - pos[i]).dot(lat);
    let extent = topo.reach[c.index()] + (pos[c.index()] - pos[i]).length();
    let goes_on = considered == 1 && !ctx.is_leaf(c);
    if off.abs() < 0.15 * extent || goes_on {
        return None;
    }
    Some(if off > 0.0 { Side::Left } else { Side::Right })
}

/// Limbs on the ground stand on it together: one whose lowest joint stays clearly above the
/// lowest standing limb's is not on the ground (a long arm hanging to the knees, which a
/// cartoon's big head, raising the body's height, brought within the ground band, read as
/// a second pair of legs).
fn stand_together(limbs: &mut [Limb], hext: f32) {
    let lowest = limbs
        .iter()
        .filter(|l| l.ground)
        .map(|l| l.low)
        .fold(f32::MAX, f32::min);
    for l in limbs {
        l.ground &= l.low < lowest + 0.12 * hext;
    }
}

/// Per shape among `p`'s children (not detached): how many, and the first two.
fn twins_of(ctx: &Ctx<'_>, p: BoneId) -> HashMap<u64, (usize, BoneId, BoneId)> {
    let mut shapes: HashMap<u64, (usize, BoneId, BoneId)> = HashMap::new();
    for &c in ctx.skel.children(p) {
        if ctx.detached[c.index()] {
            continue;
        }
        let e = shapes.entry(ctx.topo.hash[c.index()]).or_insert((0, c, c));
        e.0 += 1;
        if e.0 == 2 {
            e.2 = c;
        }
    }
    shapes
}

/// The offset along `lat` of child `c`'s own joint from `p`'s, when `c` has exactly one
/// mirror twin among `p`'s children (`twins`, see [`twins_of`]) and their joints (the first
/// down their chains that part, past zero-length helpers) lie on either side of `p`: twins
/// that part at their roots are a pair of limbs, even when one swings across the body (a
/// walk's crossing leg, whose foot under the hips puts its subtree's centroid on the midline).
fn twin_offset(
    ctx: &Ctx<'_>,
    p: BoneId,
    c: BoneId,
    twins: &HashMap<u64, (usize, BoneId, BoneId)>,
    lat: Vec3,
) -> Option<f32> {
    let &(n, a, b) = twins.get(&ctx.topo.hash[c.index()])?;
    if n != 2 {
        return None;
    }
    let other = if a == c { b } else { a };
    let (x, y) = ctx.topo.parted(ctx.pos, c, other, 0.02 * ctx.size);
    let at = |j: BoneId| (ctx.pos[j.index()] - ctx.pos[p.index()]).dot(lat);
    let (ox, oy) = (at(x), at(y));
    let clear = 0.005 * ctx.size;
    (ox * oy < 0.0 && ox.abs() > clear && oy.abs() > clear).then_some(ox)
}

/// The centerline turned to run tail → head: its head end is the higher and more forward one.
pub(super) fn oriented(ctx: &Ctx<'_>, mut path: Vec<BoneId>) -> Vec<BoneId> {
    if let (Some(&a), Some(&b)) = (path.first(), path.last()) {
        let score =
            |x: BoneId| ctx.pos[x.index()].dot(ctx.up) + 0.7 * ctx.pos[x.index()].dot(ctx.forward);
        if score(a) > score(b) {
            path.reverse();
        }
    }
    path
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
        low,
        height: height / k,
    }
}

/// The body's line through the central tree: the path that holds the most body, scored by its
/// length plus the reach of every mirrored limb pair hanging from a bone on it. The body is what
/// joins its limbs, so a chain longer than the spine that joins none (a backpack, a cape, hair)
/// loses to the path through the hips the legs hang from; on an ordinary rig the longest path
/// already holds every pair and wins as before.
pub(super) fn centerline(ctx: &Ctx<'_>, central: &[bool], limbs: &[Limb]) -> Vec<BoneId> {
    let n = central.len();
    let mut weight = vec![0.0f32; n];
    for l in limbs.iter().filter(|l| l.members.len() == 2) {
        weight[l.parent.index()] += l.reach;
    }
    // The central tree parents first; one pass back from its leaves gives each bone its best downward path: `down` its value,
    // `next` its child. A tiny per-edge term lets zero-length helpers still extend a path.
    let Some(root) = (0..n).find(|&i| central[i]) else {
        return Vec::new();
    };
    let order = central_preorder(ctx, central, root);
    let edge = |p: usize, c: usize| (ctx.pos[c] - ctx.pos[p]).length() + 1e-4 * ctx.size;
    let mut down = vec![0.0f32; n];
    let mut next: Vec<Option<usize>> = vec![None; n];
    let mut best: Option<(f32, usize, Option<usize>)> = None;
    for &b in order.iter().rev() {
        let mut top: [Option<(f32, usize)>; 2] = [None, None];
        for c in ctx.skel.children(BoneId(b as u16)) {
            let c = c.index();
            if !central[c] {
                continue;
            }
            let v = edge(b, c) + down[c];
            if top[0].is_none_or(|(t, _)| v > t + 1e-6) {
                top[1] = top[0];
                top[0] = Some((v, c));
            } else if top[1].is_none_or(|(t, _)| v > t + 1e-6) {
                top[1] = Some((v, c));
            }
        }
        down[b] = weight[b] + top[0].map_or(0.0, |t| t.0);
        next[b] = top[0].map(|t| t.1);
        let through = down[b] + top[1].map_or(0.0, |t| t.0);
        if best.is_none_or(|(v, ..)| through > v + 1e-6) {
            best = Some((through, b, top[1].map(|t| t.1)));
        }
    }
    let Some((_, apex, second)) = best else {
        return Vec::new();
    };
    path_through(&next, apex, second)
}

/// The central tree from `root`, parents before children (an explicit stack: no recursion on
/// the file's depth).
fn central_preorder(ctx: &Ctx<'_>, central: &[bool], root: usize) -> Vec<usize> {
    let mut order = Vec::new();
    let mut stack = vec![root];
    while let Some(b) = stack.pop() {
        order.push(b);
        stack.extend(
            ctx.skel
                .children(BoneId(b as u16))
                .iter()
                .map(|c| c.index())
                .filter(|&c| central[c]),
        );
    }
    order
}

/// The path from the far end of `apex`'s best branch up to it, then down its `second` branch
/// (each bone's best child in `next`).
fn path_through(next: &[Option<usize>], apex: usize, second: Option<usize>) -> Vec<BoneId> {
    let walk = |mut b: usize| {
        let mut out = vec![BoneId(b as u16)];
        while let Some(c) = next[b] {
            out.push(BoneId(c as u16));
            b = c;
        }
        out
    };
    let mut path: Vec<BoneId> = walk(apex).into_iter().rev().collect();
    if let Some(s) = second {
        path.extend(walk(s));
    }
    path
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use crate::analysis::{analyze, Role, SkeletonView};
    use crate::fk::world_transforms;
    use crate::skeleton::{BoneId, Skeleton};

    #[test]
    fn a_shuffled_anonymous_human_has_the_same_centerline() {
        let named = crate::corpus::get("cmu_cgspeed").expect("corpus");
        let anon = crate::corpus::get("cmu_cgspeed_anon").expect("corpus");
        let roles = |e: &crate::corpus::CorpusEntry| {
            let a = analyze(&SkeletonView::rest(&e.skeleton));
            let mut central: Vec<String> = e
                .skeleton
                .bone_ids()
                .filter(|b| {
                    matches!(
                        a.roles[b.index()].role,
                        Role::Hips
                            | Role::Spine
                            | Role::SpineMid
                            | Role::Chest
                            | Role::Neck(_)
                            | Role::Head
                    )
                })
                .map(|b| e.labels[b.index()].clone())
                .collect();
            central.sort();
            central
        };
        let r = roles(&named);
        assert!(r.len() >= 5, "{r:?}");
        assert_eq!(r, roles(&anon));
    }

    /// `skel` with bone `b` turned by `turn` about its joint, in world space, as its rest.
    fn turned(skel: &Skeleton, b: BoneId, turn: Quat) -> Skeleton {
        let w = world_transforms(skel, &skel.rest_pose());
        let parent = skel
            .parent(b)
            .map_or(Quat::IDENTITY, |p| w[p.index()].rotation);
        let mut raw = skel.to_raw();
        raw.bones[b.index()].rest.rotation =
            (parent.inverse() * turn * w[b.index()].rotation).normalize();
        Skeleton::build(&raw).expect("skeleton")
    }

    /// Read without names, a crossover step (the right foot swung half the hips' width past
    /// the midline, so its leg's joints average to the middle) and a head tilted 25° over its
    /// neck keep every core role: mirror twins that part at their roots are a pair of limbs,
    /// and a central bone's only child that goes on continues the body.
    #[test]
    fn a_crossing_leg_and_a_tilted_head_keep_their_roles() {
        let e = crate::corpus::get("mixamo").expect("corpus");
        let find = |l: &str| {
            let b = e.skeleton.bone_ids().find(|b| e.labels[b.index()] == l);
            b.expect(l)
        };
        let w = world_transforms(&e.skeleton, &e.skeleton.rest_pose());
        let at = |b: BoneId| w[b.index()].translation;
        let (hips, thigh, foot) = (find("hips"), find("right_upper_leg"), find("right_foot"));
        let side = (at(thigh) - at(hips)).x;
        let down = (at(foot) - at(thigh)).length();
        let swing = -side.signum() * (1.5 * side.abs() / down).atan();
        let crossed = turned(&e.skeleton, thigh, Quat::from_rotation_z(swing));
        let tilted = turned(
            &crossed,
            find("neck"),
            Quat::from_rotation_z(25f32.to_radians()),
        );
        let w = world_transforms(&tilted, &tilted.rest_pose());
        let past = (w[foot.index()].translation - w[hips.index()].translation).x;
        assert!(
            past * side < 0.0,
            "the foot crossed the midline: {past} against {side}"
        );
        let blind = tilted.renamed(|b, _| format!("j{}", b.0)).expect("rename");
        let a = analyze(&SkeletonView::rest(&blind));
        let core = [
            "hips",
            "neck",
            "head",
            "upper_leg",
            "lower_leg",
            "foot",
            "upper_arm",
            "lower_arm",
            "hand",
        ];
        let mut checked = 0;
        for b in blind.bone_ids() {
            let want = &e.labels[b.index()];
            let side = want
                .trim_start_matches("left_")
                .trim_start_matches("right_");
            if core.contains(&side) {
                assert_eq!(&a.label(b), want, "bone {}", e.skeleton.name(b));
                checked += 1;
            }
        }
        assert_eq!(checked, 15);
    }
}
