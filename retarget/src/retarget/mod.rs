//! Retargeting: a source pose (on its own skeleton) becomes a pose of a differently built target.
//!
//! ```text
//!  build (once):  sources' + target's reference postures (rest by default)
//!                 MappingTable ──▶ per target bone: links to source bone(s) with
//!                                  offset = Ws0⁻¹ · A · Wt0   (A: rest-posture alignment)
//!                                  segment end joints, options, delay slots, root plan
//!  apply (per frame, no allocation):
//!     source pose ─FK─▶ history ring ─▶ for each target bone (parents first):
//!        world = C · Ws(t) · offset          C: swing so the bone points along the source
//!                                               segment between the mapped end joints
//!        (several sources: sign-aligned, normalised weighted quaternion average)
//!        local = parent_world⁻¹ · world     then reverse / weight options
//!        posture-relative bones (a walker driving a quadruped, `RetargetOptions::
//!        posture_relative`): world = D · yaw · Wt0, D = Ws(t) · Ws_stand⁻¹ (the source's
//!        motion from its standing posture), or only D's turn about up (a level trunk);
//!        no A, no C: the target keeps its own posture
//!     root: hips = floor_t + ratio · (source hips − floor_s) along the source's up,
//!           horizontal travel × ratio, ratio = leg lengths between mapped joints (measured on
//!           the target's aligned reference, in the source's world); feet calibrated onto the
//!           floor on the first frame (FootContact)
//! ```
//!
//! Why world space: copying local rotations (even rest-normalised, REFERENCE §3) is only right
//! when both rests show the same posture and the chains have the same bones. Working with each
//! bone's world rotation relative to its reference, plus a direction fix from the positions of
//! the segment's mapped end joints, makes A-pose vs T-pose, arbitrary bind poses, differing bone
//! axes and chains of different lengths come out pointing the same way. Unmapped bones keep their
//! rest local rotation, so a longer target chain bends rigidly with its mapped parent, unless
//! `RetargetOptions::distribute_chains` spreads the bend over the unmapped bones inside it.

mod align;
mod build;
mod carried;
mod history;
mod options;
mod root;
pub mod workloads;

use std::sync::Arc;

use glam::{Quat, Vec3};

use crate::clip::Clip;
use crate::error::RetargetError;
use crate::fk::WorldTransform;
use crate::mapping::{BoneOptions, MappingTable, SourceRef};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};
use history::History;
use root::RootPlan;

/// Which percentile of the frames' lowest foot heights is a clip's floor: low enough that a
/// foot stands there in most clips, high enough that a few frames dipping lower do not count.
pub const FLOOR_PERCENTILE: usize = 5;

pub use options::{Follow, FootContact, RetargetOptions, RootMotion};
pub use root::FloorAt;

/// Marks a link without a direction fix.
const NO_END: u16 = u16::MAX;

/// One source bone driving one target bone, with everything precomputed.
#[derive(Debug, Clone, Copy)]
struct Link {
    input: u16,
    bone: u16,
    /// Source joint the target segment's mapped end corresponds to, or `NO_END`.
    end: u16,
    /// Normalised over the target bone's links.
    weight: f32,
    /// `Ws0⁻¹ · A · Wt0`: source world rotation → target world rotation.
    offset: Quat,
    /// For a posture-relative link, the source bone's standing world rotation (`Ws0` of its
    /// offset): what the aligned rest evaluates instead of the source's reference, so the
    /// target shows its own posture there.
    standing: Option<Quat>,
    /// A posture-relative link that takes only the heading of the source's rotation from its
    /// standing posture ([`Follow::Heading`]).
    heading_only: bool,
    delay_frames: u32,
}

/// Per target bone.
#[derive(Debug, Clone, Copy)]
struct BonePlan {
    first_link: u32,
    num_links: u32,
    /// The segment direction in the bone's own frame (for the direction fix).
    dir_local: Vec3,
    options: BoneOptions,
    rest_local: Quat,
    /// Local rotation when every source shows its reference posture (the base for `reverse`).
    aligned_local: Quat,
    /// Unmapped bones between this mapped bone and its mapped end (`Mapping::chain_bones`),
    /// which share its bend, and that end.
    chain_first: u32,
    chain_len: u16,
    chain_end: u16,
    /// For such an unmapped interior bone: the mapped bone whose bend it shares (`NO_END` if
    /// none), and its frame relative to that bone's at rest.
    curl_root: u16,
    curl_frame: Quat,
}

/// The per-frame plan of a retargeting job, built once from (source skeleton(s), target
/// skeleton, [`MappingTable`](crate::mapping::MappingTable), options): rest alignment,
/// offsets, chains and root motion, precomputed. Immutable once built: share it
/// (`Arc<RetargetPlan>`) between every performer that drives the same pair, each with its own
/// [`RetargetContext`] (like ozz's `SamplingJob` and its `Context`).
#[derive(Debug, Clone)]
pub struct RetargetPlan {
    sources: Vec<Skeleton>,
    target: Skeleton,
    bones: Vec<BonePlan>,
    links: Vec<Link>,
    root: Option<RootPlan>,
    /// Interior chains (see `BonePlan::chain_first`).
    chain_bones: Vec<u16>,
    /// The sources' up (unit): what [`Follow::Heading`] links turn about.
    up: Vec3,
    /// Bones carried at a limb's end from beside it (IK feet under the armature root).
    carried: Vec<carried::Carried>,
}

/// The per-performer state of a retargeting job: source history (for per-bone delays),
/// scratch world transforms, this frame's chain bends and the foot-contact calibration. Made
/// by [`RetargetPlan::new_context`], sized for that plan; allocates nothing afterwards.
#[derive(Debug, Clone)]
pub struct RetargetContext {
    history: Vec<History>,
    scratch: Vec<WorldTransform>,
    /// Per chain root, this frame's share of its bend.
    curl: Vec<Quat>,
    /// The `FirstFrame` foot-contact correction, once measured.
    vertical_offset: Option<f32>,
}

impl RetargetContext {
    /// Forgets the delay history and the foot calibration (e.g. after a source restarts or
    /// seeks).
    pub fn reset(&mut self) {
        for h in &mut self.history {
            h.reset();
        }
        self.vertical_offset = None;
    }
}

/// A plan with one context: the retargeting job of one performer. [`Mapping::build`] makes
/// both; everything the plan answers is reachable through `Deref`. Cloning is cheap (the plan
/// is shared) and gives the clone its own context.
///
/// Call [`Mapping::apply`] (or [`Mapping::apply_one`]) once per frame; it allocates nothing.
#[derive(Debug, Clone)]
pub struct Mapping {
    plan: Arc<RetargetPlan>,
    context: RetargetContext,
}

impl std::ops::Deref for Mapping {
    type Target = RetargetPlan;

    fn deref(&self) -> &RetargetPlan {
        &self.plan
    }
}

impl Mapping {
    /// A job of `plan` with a fresh context.
    pub fn from_plan(plan: Arc<RetargetPlan>) -> Mapping {
        let context = plan.new_context();
        Mapping { plan, context }
    }

    /// The shared plan.
    pub fn plan(&self) -> &Arc<RetargetPlan> {
        &self.plan
    }

    /// Retargets one frame: `sources[i]` is the current pose of input `i`; writes every bone of
    /// `out` (a pose of the target skeleton). Allocates nothing. Errors only when the poses do
    /// not fit the skeletons this mapping was built for.
    pub fn apply(&mut self, sources: &[&Pose], out: &mut Pose) -> Result<(), RetargetError> {
        self.plan.apply(&mut self.context, sources, out)
    }

    /// [`Mapping::apply`] for a mapping with a single source input.
    pub fn apply_one(&mut self, source: &Pose, out: &mut Pose) -> Result<(), RetargetError> {
        self.apply(&[source], out)
    }

    /// Forgets the delay history (e.g. after a source restarts or seeks).
    pub fn reset(&mut self) {
        self.context.reset();
    }

    /// Sets the source floor height (see [`RetargetOptions::source_floor_y`]); a plan shared
    /// with other jobs is copied first.
    pub fn set_source_floor_y(&mut self, y: f32) {
        Arc::make_mut(&mut self.plan).set_source_floor_y(y);
        self.context.vertical_offset = None;
    }

    /// Retargets a whole clip from the single source input (offline use; allocates the result).
    /// Per-bone delays count in calls, so build with `frame_time_secs` = the clip's frame time.
    pub fn apply_clip(&mut self, clip: &Clip) -> Result<Clip, RetargetError> {
        self.reset();
        let target = std::sync::Arc::new(self.target.clone());
        let mut poses = Vec::with_capacity(clip.num_frames());
        let mut out = self.target.rest_pose();
        for p in &clip.poses {
            self.apply_one(p, &mut out)?;
            poses.push(out.clone());
        }
        self.reset();
        Clip::new(clip.name.clone(), target, poses, clip.frame_time_secs)
    }
}

impl RetargetPlan {
    /// A context for this plan: history deep enough for the longest delay on each input.
    pub fn new_context(&self) -> RetargetContext {
        let history = self
            .sources
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let longest = self
                    .links
                    .iter()
                    .filter(|l| l.input as usize == i)
                    .map(|l| l.delay_frames as usize)
                    .max()
                    .unwrap_or(0);
                History::new(s.num_bones(), longest + 1)
            })
            .collect();
        RetargetContext {
            history,
            scratch: vec![WorldTransform::IDENTITY; self.target.num_bones()],
            curl: vec![Quat::IDENTITY; self.target.num_bones()],
            vertical_offset: None,
        }
    }

    /// Retargets one frame with `context` (one of this plan's): see [`Mapping::apply`].
    pub fn apply(
        &self,
        context: &mut RetargetContext,
        sources: &[&Pose],
        out: &mut Pose,
    ) -> Result<(), RetargetError> {
        if sources.len() != self.sources.len() {
            return Err(RetargetError::PoseSizeMismatch {
                expected: self.sources.len(),
                got: sources.len(),
            });
        }
        if context.history.len() != self.sources.len()
            || context.scratch.len() != self.target.num_bones()
        {
            return Err(RetargetError::ForeignContext);
        }
        for (pose, skel) in sources.iter().zip(&self.sources) {
            pose.check(skel)?;
        }
        out.check(&self.target)?;
        self.solve(context, sources, out, true);
        Ok(())
    }

    /// The target skeleton.
    pub fn target(&self) -> &Skeleton {
        &self.target
    }

    /// The skeleton of source input `input`.
    pub fn source(&self, input: usize) -> Option<&Skeleton> {
        self.sources.get(input)
    }

    /// Number of source inputs.
    pub fn num_inputs(&self) -> usize {
        self.sources.len()
    }

    /// A target pose to pass to [`Mapping::apply`] (the target's rest pose).
    pub fn new_target_pose(&self) -> Pose {
        self.target.rest_pose()
    }

    /// The target pose produced while every source holds its reference posture: the target's
    /// rest re-posed into the source's posture (e.g. an A-pose character shown in T-pose),
    /// with every carried bone at its limb's end, as [`Mapping::apply`] places it.
    pub fn aligned_rest_pose(&self) -> Pose {
        let mut p = self.target.rest_pose();
        for (r, plan) in p.rotations.iter_mut().zip(&self.bones) {
            *r = plan.aligned_local;
        }
        if !self.carried.is_empty() {
            let mut worlds = crate::fk::world_transforms(&self.target, &p);
            carried::carry(&self.carried, &self.target, &mut worlds, &mut p);
        }
        p
    }

    /// The target bone that receives root motion (the shallowest mapped one, normally the hips).
    pub fn root_bone(&self) -> Option<BoneId> {
        self.root.as_ref().map(|r| r.bone)
    }

    /// Target / source leg-length ratio applied to root translation.
    pub fn root_scale(&self) -> Option<f32> {
        self.root.as_ref().map(|r| r.scale)
    }

    /// The source's floor over a clip of the root input: how low its foot joints get, as the
    /// [`FLOOR_PERCENTILE`]th percentile of each frame's lowest (where they stand when planted). `None` without root motion or frames. Offline
    /// helper (allocates); pass the result to [`Mapping::set_source_floor_y`].
    pub fn measure_source_floor(&self, poses: &[Pose]) -> Option<f32> {
        let root = self.root.as_ref()?;
        let skel = self.sources.get(root.input as usize)?;
        let mut worlds = vec![WorldTransform::IDENTITY; skel.num_bones()];
        let mut lows: Vec<f32> = Vec::with_capacity(poses.len());
        for p in poses {
            if p.check(skel).is_err() {
                continue;
            }
            crate::fk::forward_kinematics(skel, p, &mut worlds);
            let low = (root.contact_bones.iter())
                .map(|b| worlds[b.index()].translation.dot(root.up))
                .fold(f32::INFINITY, f32::min);
            if low.is_finite() {
                lows.push(low);
            }
        }
        // Not the single lowest frame: a toe dipping through the floor for a frame or two (a
        // toe-off, a marker glitch) would put the floor there and every stance above it, so
        // the whole target would float. Most frames have a foot on the floor.
        lows.sort_by(f32::total_cmp);
        lows.get(lows.len() * FLOOR_PERCENTILE / 100).copied()
    }

    /// Sets the source floor height (see [`RetargetOptions::source_floor_y`]); contexts
    /// calibrated against the old floor want a [`RetargetContext::reset`].
    pub fn set_source_floor_y(&mut self, y: f32) {
        if let Some(r) = self.root.as_mut() {
            r.source_floor_y = y;
        }
    }

    /// The floor the target stands on in the output's world: the up direction (the source's,
    /// unit), the floor's height along it, and what that height is the standing height of.
    /// `None` without root motion.
    pub fn target_floor(&self) -> Option<(Vec3, f32, FloorAt)> {
        let r = self.root.as_ref()?;
        let height = r.target_floor_y.unwrap_or(r.scale * r.source_floor_y);
        Some((r.up, height, r.floor_at))
    }

    /// Whether the target's floor is known from its own reference posture (a character
    /// authored standing on the ground, or a floor given in the options), rather than carried
    /// over from the source's (a rest floating at the origin, like CMU's).
    pub fn target_posture_stands(&self) -> bool {
        self.root
            .as_ref()
            .is_some_and(|r| r.target_floor_y.is_some())
    }

    /// Whether the root travels over the ground with the source's ([`RootMotion::Scaled`]).
    /// An in-place or fixed root stays over its spot: nothing may carry it away.
    pub fn root_travels(&self) -> bool {
        self.root
            .as_ref()
            .is_some_and(|r| r.motion == RootMotion::Scaled)
    }

    /// The source input that drives root motion (the one whose legs the target's follow).
    pub fn root_input(&self) -> Option<usize> {
        self.root.as_ref().map(|r| r.input as usize)
    }

    /// Number of target bones driven by at least one source bone.
    pub fn num_mapped(&self) -> usize {
        self.bones.iter().filter(|b| b.num_links > 0).count()
    }

    /// The per-frame work, shared by `apply` and by `build` (which computes the aligned rest:
    /// `with_options` off, posture-relative links then show their standing posture).
    fn solve(
        &self,
        ctx: &mut RetargetContext,
        sources: &[&Pose],
        out: &mut Pose,
        with_options: bool,
    ) {
        for ((h, skel), pose) in ctx.history.iter_mut().zip(&self.sources).zip(sources) {
            h.push(skel, pose);
        }
        let parents = self.target.parents();
        let rest = self.target.rest();
        for t in 0..self.bones.len() {
            let parent = match parents[t] {
                Some(p) => ctx.scratch[p.index()],
                None => WorldTransform::IDENTITY,
            };
            let plan = &self.bones[t];
            let (local, world_rotation) = if plan.num_links == 0 {
                let local = self.unmapped_local(plan, ctx, with_options);
                (local, parent.rotation * local)
            } else {
                let world = self.blend_links(plan, ctx, with_options);
                let local = (parent.rotation.inverse() * world).normalize();
                if with_options && plan.chain_len > 0 {
                    let (local, world, share) =
                        self.distribute(plan, parent.rotation, local, world);
                    ctx.curl[t] = share;
                    (local, world)
                } else {
                    (local, world)
                }
            };
            let mut translation = rest[t].translation;
            let mut position = parent.translation + parent.rotation * translation;
            if let Some(root) = self.root.as_ref().filter(|r| r.bone.index() == t) {
                position = root_position(root, ctx);
                translation = parent.rotation.inverse() * (position - parent.translation);
            }
            ctx.scratch[t] = WorldTransform {
                rotation: world_rotation,
                translation: position,
            };
            out.translations[t] = translation;
            out.rotations[t] = if with_options {
                apply_options(&plan.options, plan.rest_local, plan.aligned_local, local)
            } else {
                local
            };
        }
        carried::carry(&self.carried, &self.target, &mut ctx.scratch, out);
        // The legs carrying them hang from the root: a carried bone goes where its leg goes.
        let moved = self.place_feet(ctx, out);
        carried::shift(&self.carried, &self.target, moved, &mut ctx.scratch, out);
    }
}

impl RetargetPlan {
    /// The local rotation of a bone no source drives: its rest, or, inside a longer target
    /// chain, the chain root's share of the bend.
    fn unmapped_local(&self, plan: &BonePlan, ctx: &RetargetContext, with_options: bool) -> Quat {
        if with_options && plan.curl_root != NO_END {
            let share = ctx.curl[plan.curl_root as usize];
            plan.rest_local * plan.curl_frame.inverse() * share * plan.curl_frame
        } else {
            plan.rest_local
        }
    }

    /// The world rotation a mapped bone's source links give, blended by their weights (each
    /// link's rotation with its offset, turned to point where its source bone points; without
    /// the options, a standing link holds its standing rotation).
    fn blend_links(&self, plan: &BonePlan, ctx: &RetargetContext, with_options: bool) -> Quat {
        let first = plan.first_link as usize;
        let mut blended = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
        let mut reference = Quat::IDENTITY;
        for (k, link) in self.links[first..first + plan.num_links as usize]
            .iter()
            .enumerate()
        {
            let worlds = ctx.history[link.input as usize].get(link.delay_frames as usize);
            let ws = worlds[link.bone as usize];
            let held = link.standing.filter(|_| !with_options);
            let mut q = held.unwrap_or(ws.rotation) * link.offset;
            if let (Some(standing), true, None) = (link.standing, link.heading_only, held) {
                let turn = ws.rotation * standing.inverse();
                q = heading(turn, self.up) * standing * link.offset;
            }
            if link.end != NO_END {
                let to_end = worlds[link.end as usize].translation - ws.translation;
                if let Some(d) = to_end.try_normalize() {
                    let predicted = q * plan.dir_local;
                    q = Quat::from_rotation_arc(predicted, d) * q;
                }
            }
            if k == 0 {
                reference = q;
            } else if reference.dot(q) < 0.0 {
                q = -q;
            }
            blended += q * link.weight;
        }
        blended.normalize()
    }
}

/// Where the root goes this frame: height along the source's up, measured from each side's
/// floor; the rest is horizontal travel, scaled by the leg-length ratio (or none, or the
/// reference position, by the root motion).
fn root_position(root: &RootPlan, ctx: &RetargetContext) -> Vec3 {
    let src = ctx.history[root.input as usize].get(0)[root.source_bone.index()].translation;
    let (s, up) = (root.scale, root.up);
    let floor_t = root.target_floor_y.unwrap_or(s * root.source_floor_y);
    let y = floor_t + s * (src.dot(up) - root.source_floor_y);
    let flat = |v: Vec3| v - up * v.dot(up);
    match root.motion {
        RootMotion::Scaled => flat(src) * s + up * y,
        RootMotion::InPlace => flat(root.reference_position) + up * y,
        RootMotion::Fixed => root.reference_position,
    }
}

impl RetargetPlan {
    /// Spreads a mapped bone's bend (relative to its aligned rest) evenly over itself and the
    /// unmapped bones between it and its mapped end, then swings it so the chain's chord still
    /// points where the rigid solution pointed. Returns (local, world, per-bone share).
    fn distribute(
        &self,
        plan: &BonePlan,
        parent: Quat,
        local: Quat,
        world: Quat,
    ) -> (Quat, Quat, Quat) {
        let n = plan.chain_len as f32 + 1.0;
        let mut bend = plan.aligned_local.inverse() * local;
        if bend.w < 0.0 {
            bend = -bend;
        }
        let share = Quat::IDENTITY.slerp(bend, 1.0 / n).normalize();
        let curled = parent * plan.aligned_local * share;
        // The chord to the mapped end, in the curled bone's frame.
        let rest = self.target.rest();
        let (mut frame, mut chord) = (Quat::IDENTITY, Vec3::ZERO);
        let first = plan.chain_first as usize;
        for &c in &self.chain_bones[first..first + plan.chain_len as usize] {
            let cp = &self.bones[c as usize];
            chord += frame * rest[c as usize].translation;
            frame = frame * cp.rest_local * cp.curl_frame.inverse() * share * cp.curl_frame;
        }
        chord += frame * rest[plan.chain_end as usize].translation;
        let wanted = world * plan.dir_local;
        let world = match ((curled * chord).try_normalize(), wanted.try_normalize()) {
            (Some(now), Some(wanted)) => {
                (Quat::from_rotation_arc(now, wanted) * curled).normalize()
            }
            _ => curled,
        };
        ((parent.inverse() * world).normalize(), world, share)
    }
}

/// The twist of `q` about the unit axis `up` (its heading); identity when undefined.
#[inline]
pub(super) fn heading(q: Quat, up: Vec3) -> Quat {
    let along = up * Vec3::new(q.x, q.y, q.z).dot(up);
    let twist = Quat::from_xyzw(along.x, along.y, along.z, q.w);
    if twist.length_squared() > 1e-12 {
        twist.normalize()
    } else {
        Quat::IDENTITY
    }
}

/// Per-bone options on the computed local rotation: `reverse` inverts the motion relative to the
/// aligned rest, `weight` blends from the bone's rest towards the result.
#[inline]
fn apply_options(opts: &BoneOptions, rest_local: Quat, aligned_local: Quat, local: Quat) -> Quat {
    let mut q = local;
    if opts.reverse {
        let motion = aligned_local.inverse() * q;
        q = (aligned_local * motion.inverse()).normalize();
    }
    if opts.weight < 1.0 {
        let mut target = q;
        if rest_local.dot(target) < 0.0 {
            target = -target;
        }
        q = rest_local.slerp(target, opts.weight.max(0.0)).normalize();
    }
    q
}

// Here rather than in build.rs: root.rs needs it too, and build.rs uses root.rs.
/// The first source with a positive weight.
fn primary(table: &MappingTable, t: BoneId) -> Option<SourceRef> {
    table
        .get(t)
        .and_then(|e| e.sources.iter().find(|s| s.weight > 0.0).copied())
}
