//! `Mapping::build`: everything per-frame code needs, computed once from the skeletons'
//! reference postures and the mapping table.

use std::cmp::Reverse;

use glam::{Quat, Vec3};

use super::root::{RootPlan, Side};
use super::{
    align, primary, BonePlan, Follow, Link, Mapping, RetargetOptions, RetargetPlan, NO_END,
};
use crate::error::RetargetError;
use crate::fk::{world_transforms, WorldTransform};
use crate::mapping::{BoneOptions, MappingTable, SourceRef};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// Hard cap on per-bone delay history, in frames (60 s at 240 Hz).
pub const MAX_DELAY_FRAMES: u32 = 60 * 240;

fn reference_pose(skel: &Skeleton, given: Option<&Pose>) -> Result<Pose, RetargetError> {
    match given {
        Some(p) => {
            p.check(skel)?;
            Ok(p.clone())
        }
        None => Ok(skel.rest_pose()),
    }
}

/// Checks what `build` cannot work without.
fn validate(
    sources: &[&Skeleton],
    target: &Skeleton,
    table: &MappingTable,
    opts: &RetargetOptions,
) -> Result<(), RetargetError> {
    if sources.is_empty() {
        return Err(RetargetError::InvalidMapping {
            reason: "at least one source skeleton is needed".into(),
        });
    }
    if sources.len() > u16::MAX as usize {
        return Err(RetargetError::InvalidMapping {
            reason: format!("{} source inputs; at most 65535", sources.len()),
        });
    }
    table.validate(sources, target)?;
    if !(opts.frame_time_secs.is_finite() && opts.frame_time_secs > 0.0) {
        return Err(RetargetError::BadFrameTime {
            frame_time_secs: opts.frame_time_secs as f64,
        });
    }
    if let Some(s) = opts.root_scale {
        if !(s.is_finite() && s > 0.0) {
            return Err(RetargetError::InvalidMapping {
                reason: format!("root scale {s} is not a positive finite number"),
            });
        }
    }
    Ok(())
}

/// Both sides in their reference postures, and what `build` derives from them.
struct Setup<'a> {
    sources: &'a [&'a Skeleton],
    target: &'a Skeleton,
    table: &'a MappingTable,
    opts: &'a RetargetOptions,
    src_ref: Vec<Pose>,
    src_w: Vec<Vec<WorldTransform>>,
    /// Per input, its standing posture (`RetargetOptions::source_standing`) turned to face
    /// like its reference: what `posture_relative` bones measure the motion from.
    stand_w: Vec<Vec<WorldTransform>>,
    src_eps: Vec<f32>,
    tgt_w: Vec<WorldTransform>,
    tgt_eps: f32,
    /// Turns the target's facing onto the source's.
    yaw: Quat,
    max_delay_frames: u32,
}

/// A target bone's segment in its reference posture.
struct TargetSegment {
    /// The nearest mapped descendant continuing the chain (the direction fix aims at it).
    mapped_end: Option<BoneId>,
    /// Unit direction of the segment (to `mapped_end`, else to the most chain-like child).
    direction: Vec3,
    /// The next mapped segment's end, and that segment's direction (the bend plane).
    next_end: Option<BoneId>,
    bend: Vec3,
}

impl<'a> Setup<'a> {
    fn new(
        sources: &'a [&'a Skeleton],
        target: &'a Skeleton,
        table: &'a MappingTable,
        opts: &'a RetargetOptions,
    ) -> Result<Setup<'a>, RetargetError> {
        let mut src_ref = Vec::with_capacity(sources.len());
        for (i, s) in sources.iter().enumerate() {
            let given = opts.source_reference.get(i).and_then(Option::as_ref);
            src_ref.push(reference_pose(s, given)?);
        }
        let tgt_ref = reference_pose(target, opts.target_reference.as_ref())?;
        let src_w: Vec<Vec<WorldTransform>> = sources
            .iter()
            .zip(&src_ref)
            .map(|(s, p)| world_transforms(s, p))
            .collect();
        let tgt_w = world_transforms(target, &tgt_ref);
        let up = (opts.source_up)
            .and_then(|u| u.try_normalize())
            .unwrap_or(Vec3::Y);
        let mut stand_w = Vec::with_capacity(sources.len());
        for (i, s) in sources.iter().enumerate() {
            stand_w.push(match opts.source_standing.get(i).and_then(Option::as_ref) {
                Some(p) => {
                    p.check(s)?;
                    facing_like(s, world_transforms(s, p), &src_w[i], up)
                }
                None => src_w[i].clone(),
            });
        }
        let mut setup = Setup {
            sources,
            target,
            table,
            opts,
            src_eps: src_w.iter().map(|w| 1e-4 * align::extent(w)).collect(),
            tgt_eps: 1e-4 * align::extent(&tgt_w),
            src_ref,
            src_w,
            stand_w,
            tgt_w,
            yaw: Quat::IDENTITY,
            // Capped so an absurd option (even infinity) cannot size a gigabyte history ring.
            max_delay_frames: ((opts.max_delay_secs.max(0.0) / opts.frame_time_secs).round()
                as u32)
                .min(MAX_DELAY_FRAMES),
        };
        if opts.align_rest {
            if let Some(root) = setup.root_pair() {
                setup.yaw = setup.relative_yaw(root);
            }
        }
        Ok(setup)
    }

    fn is_mapped(&self, t: BoneId) -> bool {
        primary(self.table, t).is_some()
    }

    /// The target bone that carries the body (normally the hips) and the source of the
    /// mapped bone that drives most others (normally the source's hips). The body is every
    /// mapped bone that is part of a mapped chain (its parent or a child mapped too), so a
    /// mapped control beside the body (an IK foot hanging from the armature root, as shallow
    /// as the hips) is no part of it; the root is the deepest bone all of them hang from,
    /// mapped or not (legs hanging from a body bone above the spine's first mapped bone travel
    /// with it).
    fn root_pair(&self) -> Option<(BoneId, SourceRef)> {
        let (skel, n) = (self.target, self.target.num_bones());
        let mapped: Vec<bool> = skel.bone_ids().map(|t| self.is_mapped(t)).collect();
        let in_chain = |t: BoneId| {
            skel.parent(t).is_some_and(|p| mapped[p.index()])
                || skel.children(t).iter().any(|c| mapped[c.index()])
        };
        let mut body: Vec<BoneId> = (skel.bone_ids())
            .filter(|&t| mapped[t.index()] && in_chain(t))
            .collect();
        if body.is_empty() {
            body = skel.bone_ids().filter(|&t| mapped[t.index()]).collect();
        }
        // Mapped body bones at or below each bone: parents come before their children, so one
        // backward pass sums every subtree.
        let mut below = vec![0usize; n];
        for &t in &body {
            below[t.index()] = 1;
        }
        let is_body: Vec<bool> = below.iter().map(|&b| b == 1).collect();
        for i in (0..n).rev() {
            if let Some(p) = skel.parent(BoneId(i as u16)) {
                below[p.index()] += below[i];
            }
        }
        // The deepest bone holding the body (of several roots, the one holding most of it):
        // down from the top while a child holds all its body bones and it is none itself.
        let mut root = skel
            .roots()
            .max_by_key(|r| (below[r.index()], Reverse(r.0)))?;
        let all = below[root.index()];
        while !is_body[root.index()] {
            match skel.children(root).iter().find(|c| below[c.index()] == all) {
                Some(&c) => root = c,
                None => break,
            }
        }
        let driver = (body.iter().copied())
            .min_by_key(|&t| (Reverse(below[t.index()]), skel.depth(t), t.0))?;
        primary(self.table, driver).map(|s| (root, s))
    }

    /// Relative facing of the two characters, from all mapped pairs on the root's input.
    fn relative_yaw(&self, (rt, rs): (BoneId, SourceRef)) -> Quat {
        let w = &self.src_w[rs.input as usize];
        let tw = &self.tgt_w;
        let pairs: Vec<(Vec3, Vec3)> = self
            .target
            .bone_ids()
            .filter_map(|t| {
                let s = primary(self.table, t)?;
                (s.input == rs.input).then(|| {
                    (
                        tw[t.index()].translation - tw[rt.index()].translation,
                        w[s.bone.index()].translation - w[rs.bone.index()].translation,
                    )
                })
            })
            .collect();
        align::relative_yaw(&pairs)
    }

    fn target_segment(&self, t: BoneId) -> TargetSegment {
        let (skel, w, eps) = (self.target, &self.tgt_w, self.tgt_eps);
        let mapped = |b: BoneId| self.is_mapped(b);
        // Among mapped children, the one driven by the joint the source's segment ends in,
        // when it ends in one (its only child): a forearm whose palm and thumb both start
        // below it aims at the palm the source's wrist drives, not at whichever child lies
        // nearer its line.
        let continues = |b: BoneId| {
            let (Some(ps), Some(pb)) = (primary(self.table, t), primary(self.table, b)) else {
                return false;
            };
            let kids = self.sources[ps.input as usize].children(ps.bone);
            ps.input == pb.input && kids.len() == 1 && kids[0] == pb.bone
        };
        let mapped_end = align::chain_end(skel, w, t, eps, &|b| mapped(b) && continues(b))
            .or_else(|| align::chain_end(skel, w, t, eps, &mapped))
            .or_else(|| self.detached_end(t));
        let any_end = mapped_end.or_else(|| align::chain_end(skel, w, t, eps, &|_| true));
        let direction = match any_end {
            Some(e) => align::direction(w, t, e),
            None => align::leaf_direction(skel, w, t, eps),
        };
        let next_end = mapped_end.and_then(|e| align::chain_end(skel, w, e, eps, &mapped));
        let bend = match (mapped_end, next_end) {
            (Some(e), Some(e2)) => align::direction(w, e, e2),
            _ => Vec3::ZERO,
        };
        TargetSegment {
            mapped_end,
            direction,
            next_end,
            bend,
        }
    }

    /// For a leaf target bone, the target bone driven by its source's child: where the leaf
    /// ends when that end hangs elsewhere in the target (an IK foot under the root).
    fn detached_end(&self, t: BoneId) -> Option<BoneId> {
        if !self.target.children(t).is_empty() {
            return None;
        }
        let s = primary(self.table, t)?;
        let src = self.sources.get(s.input as usize)?;
        let kids = src.children(s.bone);
        self.target.bone_ids().find(|&u| {
            u != t
                && primary(self.table, u)
                    .is_some_and(|p| p.input == s.input && kids.contains(&p.bone))
        })
    }

    /// The link from source bone `sref` to target bone `t`: the source joints matching the
    /// target segment's ends, the rest alignment and the resulting offset.
    fn link(
        &self,
        t: BoneId,
        seg: &TargetSegment,
        sref: &SourceRef,
        total: f32,
        options: &BoneOptions,
    ) -> Link {
        let input = sref.input as usize;
        let (skel, w, eps) = (self.sources[input], &self.src_w[input], self.src_eps[input]);
        let s = sref.bone;
        let delay_frames = ((options.delay_secs.max(0.0) / self.opts.frame_time_secs).round()
            as u32)
            .min(self.max_delay_frames);
        let wt0 = self.tgt_w[t.index()].rotation;
        let follow = (self.opts.posture_relative.iter()).find_map(|&(b, f)| (b == t).then_some(f));
        if let Some(follow) = follow {
            return self.posture_link(t, sref, (total, delay_frames), follow);
        }
        // The source joint a mapped target joint corresponds to, if it lies below `from`.
        // A leaf's end may hang elsewhere: an IK foot under the root is where the shin points.
        let corresponding = |tb: Option<BoneId>, from: BoneId| {
            let e = primary(self.table, tb?)?;
            let below = align::is_descendant(skel, from, e.bone) || skel.children(from).is_empty();
            (e.input == sref.input && e.bone != from && below)
                .then_some(e.bone)
                .and_then(|e| align::distinct_end(skel, w, from, e, eps))
        };
        let s_end = corresponding(seg.mapped_end, s);
        let s_any_end = s_end.or_else(|| align::chain_end(skel, w, s, eps, &|_| true));
        let p_s = match s_any_end {
            Some(e) => align::direction(w, s, e),
            None => align::leaf_direction(skel, w, s, eps),
        };
        let bend_s = s_end
            .and_then(|e| corresponding(seg.next_end, e).map(|e2| align::direction(w, e, e2)))
            .unwrap_or(Vec3::ZERO);
        let a = self.rest_alignment(seg, p_s, bend_s);
        let ws0 = w[s.index()].rotation;
        Link {
            input: sref.input,
            bone: s.0,
            end: match (self.opts.match_directions, s_end) {
                (true, Some(e)) => e.0,
                _ => NO_END,
            },
            weight: sref.weight / total,
            offset: (ws0.inverse() * a * wt0).normalize(),
            standing: None,
            heading_only: false,
            delay_frames,
        }
    }

    /// A link that keeps target bone `t`'s own posture (turned to the source's facing) while
    /// the source stands; the source's world rotation from its standing posture moves it.
    fn posture_link(
        &self,
        t: BoneId,
        sref: &SourceRef,
        (total, delay_frames): (f32, u32),
        follow: Follow,
    ) -> Link {
        let standing = self.stand_w[sref.input as usize][sref.bone.index()].rotation;
        let a = if self.opts.align_rest {
            self.yaw
        } else {
            Quat::IDENTITY
        };
        let wt0 = self.tgt_w[t.index()].rotation;
        Link {
            input: sref.input,
            bone: sref.bone.0,
            end: NO_END,
            weight: sref.weight / total,
            offset: (standing.inverse() * a * wt0).normalize(),
            standing: Some(standing),
            heading_only: follow == Follow::Heading,
            delay_frames,
        }
    }

    /// The rotation carrying the source segment (direction `p_s`, bend `bend_s`) onto the
    /// target segment `seg` at rest, the facing included; identity without rest alignment.
    fn rest_alignment(&self, seg: &TargetSegment, p_s: Vec3, bend_s: Vec3) -> Quat {
        if !self.opts.align_rest {
            return Quat::IDENTITY;
        }
        let p_t = self.yaw * seg.direction;
        let bend_t = self.yaw * seg.bend;
        // Twist from the bend plane when both limbs are bent at rest, else from a world axis
        // (forward, side or up) that means the same on both once their facing agrees.
        let swing_twist = if align::is_bent(p_t, bend_t) && align::is_bent(p_s, bend_s) {
            align::align(p_t, bend_t, p_s, bend_s)
        } else {
            let axis = align::twist_axis(p_t, p_s);
            align::align(p_t, axis, p_s, axis)
        };
        swing_twist * self.yaw
    }

    /// Per target bone: its plan and links (appended to `links`).
    fn plan_bone(&self, t: BoneId, links: &mut Vec<Link>, chains: &mut Vec<u16>) -> BonePlan {
        let rest_local = self.target.rest()[t.index()].rotation;
        let mut plan = BonePlan {
            first_link: links.len() as u32,
            num_links: 0,
            dir_local: Vec3::ZERO,
            options: BoneOptions::default(),
            rest_local,
            aligned_local: rest_local,
            chain_first: 0,
            chain_len: 0,
            chain_end: NO_END,
            curl_root: NO_END,
            curl_frame: Quat::IDENTITY,
        };
        let Some(entry) = self.table.get(t) else {
            return plan;
        };
        let total: f32 = entry.sources.iter().map(|s| s.weight).sum();
        if total <= 0.0 {
            return plan;
        }
        plan.options = entry.options;
        let seg = self.target_segment(t);
        if self.opts.match_directions && seg.mapped_end.is_some() {
            let wt0 = self.tgt_w[t.index()].rotation;
            plan.dir_local = (wt0.inverse() * seg.direction).normalize_or_zero();
        }
        for sref in entry.sources.iter().filter(|s| s.weight > 0.0) {
            links.push(self.link(t, &seg, sref, total, &entry.options));
        }
        plan.num_links = links.len() as u32 - plan.first_link;
        if let (true, Some(end)) = (self.opts.distribute_chains, seg.mapped_end) {
            let interior = self.interior(t, end);
            if !interior.is_empty() && plan.dir_local != Vec3::ZERO {
                plan.chain_first = chains.len() as u32;
                plan.chain_len = interior.len().min(u16::MAX as usize) as u16;
                plan.chain_end = end.0;
                chains.extend(interior.iter().take(plan.chain_len as usize).map(|b| b.0));
            }
        }
        plan
    }

    /// The plan, without root motion yet.
    fn plan(&self) -> RetargetPlan {
        let mut links = Vec::new();
        let mut chain_bones = Vec::new();
        let mut bones: Vec<BonePlan> = (self.target.bone_ids())
            .map(|t| self.plan_bone(t, &mut links, &mut chain_bones))
            .collect();
        // Interior bones learn which chain they belong to and their frame within it.
        for t in 0..bones.len() {
            let (first, len) = (bones[t].chain_first as usize, bones[t].chain_len as usize);
            let mut frame = Quat::IDENTITY;
            for &c in &chain_bones[first..first + len] {
                let c = c as usize;
                frame *= bones[c].rest_local;
                bones[c].curl_root = t as u16;
                bones[c].curl_frame = frame;
            }
        }
        // A leaf whose source's child drives a lone bone beside the body (hanging from above
        // the body's root, as an IK foot under the armature root does: a control, as the
        // analysis's `detached` calls it) carries it at its end.
        let skel = self.target;
        let body = self.root_pair().map(|(root, _)| root);
        let beside = |u: BoneId| {
            body.is_some_and(|root| {
                skel.children(u).is_empty()
                    && !skel.is_below(root, u)
                    && skel.parent(u).is_none_or(|p| skel.is_below(root, p))
            })
        };
        let carried = (skel.bone_ids())
            .filter_map(|t| Some((t, self.detached_end(t)?)))
            .filter(|&(_, u)| beside(u))
            .map(|(t, u)| super::carried::Carried::new(&self.tgt_w, u, t))
            .collect();
        RetargetPlan {
            carried,
            sources: self.sources.iter().map(|s| (*s).clone()).collect(),
            target: self.target.clone(),
            bones,
            links,
            root: None,
            chain_bones,
            up: (self.opts.source_up)
                .and_then(|u| u.try_normalize())
                .unwrap_or(Vec3::Y),
        }
    }

    /// What `plan` (without root motion) shows while every source holds its reference.
    fn aligned_rest(&self, plan: &RetargetPlan) -> Pose {
        let mut context = plan.new_context();
        let refs: Vec<&Pose> = self.src_ref.iter().collect();
        let mut aligned = self.target.rest_pose();
        plan.solve(&mut context, &refs, &mut aligned, false);
        aligned
    }

    /// Bones strictly between `t` and its descendant `end`, from `t` down; empty when one of
    /// them is mapped (then the chain is not `t`'s alone to bend).
    fn interior(&self, t: BoneId, end: BoneId) -> Vec<BoneId> {
        let mut path = Vec::new();
        let mut b = self.target.parent(end);
        while let Some(x) = b {
            if x == t {
                path.reverse();
                return path;
            }
            if self.is_mapped(x) {
                return Vec::new();
            }
            path.push(x);
            b = self.target.parent(x);
        }
        Vec::new()
    }
}

/// `worlds` (a posture of `skel`) turned about `up` so its root faces as in `reference`.
fn facing_like(
    skel: &Skeleton,
    mut worlds: Vec<WorldTransform>,
    reference: &[WorldTransform],
    up: Vec3,
) -> Vec<WorldTransform> {
    let Some(root) = skel.bone_ids().next() else {
        return worlds;
    };
    let turn = reference[root.index()].rotation * worlds[root.index()].rotation.inverse();
    let yaw = super::heading(turn, up);
    let pivot = worlds[root.index()].translation;
    for w in &mut worlds {
        w.rotation = (yaw * w.rotation).normalize();
        w.translation = pivot + yaw * (w.translation - pivot);
    }
    worlds
}

impl Mapping {
    /// Precomputes a retargeting job. `sources[i]` is the skeleton of input `i` (the `input` of
    /// a [`SourceRef`]); `table` has one entry per target bone. Fails when the table or a
    /// reference pose does not fit the skeletons.
    pub fn build(
        sources: &[&Skeleton],
        target: &Skeleton,
        table: &MappingTable,
        opts: &RetargetOptions,
    ) -> Result<Mapping, RetargetError> {
        validate(sources, target, table, opts)?;
        let setup = Setup::new(sources, target, table, opts)?;
        let mut plan = setup.plan();
        // The aligned rest: what the target shows while every source holds its reference.
        let aligned = setup.aligned_rest(&plan);
        for (bone, q) in plan.bones.iter_mut().zip(&aligned.rotations) {
            bone.aligned_local = *q;
        }
        // Root motion is planned on the aligned rest: the target in the source's posture and
        // world, so heights and leg lengths on both sides are measured along the same up, even
        // when the target's own rest lies along another axis (Z-up files).
        let mut aligned_w = vec![WorldTransform::IDENTITY; target.num_bones()];
        crate::fk::forward_kinematics(target, &aligned, &mut aligned_w);
        let carried: Vec<(BoneId, BoneId)> = plan.carried.iter().map(|c| c.pair()).collect();
        plan.root = setup.root_pair().map(|(rt, rs)| {
            let input = rs.input as usize;
            RootPlan::new(
                Side {
                    skel: sources[input],
                    worlds: &setup.src_w[input],
                    eps: setup.src_eps[input],
                    carried: &[],
                },
                Side {
                    skel: target,
                    worlds: &aligned_w,
                    eps: setup.tgt_eps,
                    carried: &carried,
                },
                &setup.tgt_w,
                table,
                rt,
                rs,
                opts,
            )
        });
        Ok(Mapping::from_plan(std::sync::Arc::new(plan)))
    }
}
