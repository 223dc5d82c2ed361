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
//!     root: hips position = ground_t + ratio · (source hips − ground_s), ratio = hip heights
//! ```
//!
//! Why world space: copying local rotations (even rest-normalised, REFERENCE §3) is only right
//! when both rests show the same posture and the chains have the same bones. Working with each
//! bone's world rotation relative to its reference, plus a direction fix from the positions of
//! the segment's mapped end joints, makes A-pose vs T-pose, arbitrary bind poses, differing bone
//! axes and chains of different lengths come out pointing the same way. Unmapped bones keep their
//! rest local rotation, so a longer target chain bends rigidly with its mapped parent.

mod align;
mod history;
mod options;
pub mod workloads;

use glam::{Quat, Vec3};

use crate::clip::Clip;
use crate::error::RetargetError;
use crate::fk::{world_transforms, WorldTransform};
use crate::mapping::{BoneOptions, MappingTable, SourceRef};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};
use history::History;

pub use options::{FootContact, RetargetOptions, RootMotion};

/// Legs told apart by the foot-contact calibration (more share the last slot).
const MAX_LEGS: usize = 8;

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
}

/// How the target's root bone is placed.
#[derive(Debug, Clone)]
struct RootPlan {
    bone: BoneId,
    input: u16,
    source_bone: BoneId,
    scale: f32,
    motion: RootMotion,
    source_floor_y: f32,
    /// `None`: the target's rest does not show where its floor is; it then keeps the source's
    /// floor clearance, scaled.
    target_floor_y: Option<f32>,
    reference_position: Vec3,
    /// Source bones (of `input`) at the feet: what [`Mapping::measure_source_floor`] looks at.
    contact_bones: Vec<BoneId>,
    /// (target, source) foot joint pairs for [`Mapping::place_feet`].
    /// With the index of the leg (root child subtree) each belongs to, below `MAX_LEGS`.
    contacts: Vec<(BoneId, BoneId, u8)>,
    foot_contact: FootContact,
    /// The `FirstFrame` correction, once measured.
    vertical_offset: Option<f32>,
}

/// A built retargeting job: (source skeleton(s), target skeleton, mapping table, options) with
/// rest alignment, offsets, history buffers and scratch space precomputed.
///
/// Call [`Mapping::apply`] (or [`Mapping::apply_one`]) once per frame; it allocates nothing.
/// `apply` takes `&mut self` because of the delay history; give every performer its own clone.
#[derive(Debug, Clone)]
pub struct Mapping {
    sources: Vec<Skeleton>,
    target: Skeleton,
    bones: Vec<BonePlan>,
    links: Vec<Link>,
    root: Option<RootPlan>,
    history: Vec<History>,
    scratch: Vec<WorldTransform>,
}

fn reference_pose(skel: &Skeleton, given: Option<&Pose>) -> Result<Pose, RetargetError> {
    match given {
        Some(p) => {
            p.check(skel)?;
            Ok(p.clone())
        }
        None => Ok(skel.rest_pose()),
    }
}

/// The first source with a positive weight.
fn primary(table: &MappingTable, t: BoneId) -> Option<SourceRef> {
    table
        .get(t)
        .and_then(|e| e.sources.iter().find(|s| s.weight > 0.0).copied())
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
        let src_eps: Vec<f32> = src_w.iter().map(|w| 1e-4 * align::extent(w)).collect();
        let tgt_eps = 1e-4 * align::extent(&tgt_w);
        let is_mapped = |t: BoneId| primary(table, t).is_some();

        // The root: the shallowest mapped target bone.
        let root_pair = target
            .bone_ids()
            .filter(|&t| is_mapped(t))
            .min_by_key(|&t| (target.depth(t), t.0))
            .and_then(|t| primary(table, t).map(|s| (t, s)));

        // Relative facing of the two characters, from all pairs on the root's input.
        let yaw = match (opts.align_rest, root_pair) {
            (true, Some((rt, rs))) => {
                let w = &src_w[rs.input as usize];
                let pairs: Vec<(Vec3, Vec3)> = target
                    .bone_ids()
                    .filter_map(|t| {
                        let s = primary(table, t)?;
                        (s.input == rs.input).then(|| {
                            (
                                tgt_w[t.index()].translation - tgt_w[rt.index()].translation,
                                w[s.bone.index()].translation - w[rs.bone.index()].translation,
                            )
                        })
                    })
                    .collect();
                align::relative_yaw(&pairs)
            }
            _ => Quat::IDENTITY,
        };

        let max_delay_frames = (opts.max_delay_secs.max(0.0) / opts.frame_time_secs).round() as u32;
        let mut bones = Vec::with_capacity(target.num_bones());
        let mut links = Vec::new();
        for t in target.bone_ids() {
            let rest_local = target.rest()[t.index()].rotation;
            let first_link = links.len() as u32;
            let mut plan = BonePlan {
                first_link,
                num_links: 0,
                dir_local: Vec3::ZERO,
                options: BoneOptions::default(),
                rest_local,
                aligned_local: rest_local,
            };
            let Some(entry) = table.get(t) else {
                bones.push(plan);
                continue;
            };
            let total: f32 = entry.sources.iter().map(|s| s.weight).sum();
            if total <= 0.0 {
                bones.push(plan);
                continue;
            }
            plan.options = entry.options;
            let wt0 = tgt_w[t.index()].rotation;

            // Target segment: to the nearest mapped descendant continuing the chain, else to the
            // most chain-like child.
            let mapped_end = align::chain_end(target, &tgt_w, t, tgt_eps, &is_mapped);
            let any_end =
                mapped_end.or_else(|| align::chain_end(target, &tgt_w, t, tgt_eps, &|_| true));
            let p_t = match any_end {
                Some(e) => align::direction(&tgt_w, t, e),
                None => align::leaf_direction(target, &tgt_w, t, tgt_eps),
            };
            let t_end2 =
                mapped_end.and_then(|e| align::chain_end(target, &tgt_w, e, tgt_eps, &is_mapped));
            let bend_t = match (mapped_end, t_end2) {
                (Some(e), Some(e2)) => align::direction(&tgt_w, e, e2),
                _ => Vec3::ZERO,
            };
            if opts.match_directions && mapped_end.is_some() {
                plan.dir_local = (wt0.inverse() * p_t).normalize_or_zero();
            }

            for sref in entry.sources.iter().filter(|s| s.weight > 0.0) {
                let input = sref.input as usize;
                let skel = sources[input];
                let w = &src_w[input];
                let eps = src_eps[input];
                let s = sref.bone;
                // The source joint the target's mapped end corresponds to.
                let corresponding = |tb: Option<BoneId>, from: BoneId| {
                    let e = primary(table, tb?)?;
                    (e.input == sref.input
                        && e.bone != from
                        && align::is_descendant(skel, from, e.bone))
                    .then_some(e.bone)
                    .and_then(|e| align::distinct_end(skel, w, from, e, eps))
                };
                let s_end = corresponding(mapped_end, s);
                let s_any_end = s_end.or_else(|| align::chain_end(skel, w, s, eps, &|_| true));
                let p_s = match s_any_end {
                    Some(e) => align::direction(w, s, e),
                    None => align::leaf_direction(skel, w, s, eps),
                };
                let bend_s = match s_end {
                    Some(e) => corresponding(t_end2, e)
                        .map(|e2| align::direction(w, e, e2))
                        .unwrap_or(Vec3::ZERO),
                    None => Vec3::ZERO,
                };
                let a = if opts.align_rest {
                    let p_t_turned = yaw * p_t;
                    let bend_t_turned = yaw * bend_t;
                    let swing_twist = if align::is_bent(p_t_turned, bend_t_turned)
                        && align::is_bent(p_s, bend_s)
                    {
                        align::align(p_t_turned, bend_t_turned, p_s, bend_s)
                    } else {
                        let axis = align::twist_axis(p_t_turned, p_s);
                        align::align(p_t_turned, axis, p_s, axis)
                    };
                    swing_twist * yaw
                } else {
                    Quat::IDENTITY
                };
                let ws0 = w[s.index()].rotation;
                let offset = (ws0.inverse() * a * wt0).normalize();
                let delay_frames = ((entry.options.delay_secs.max(0.0) / opts.frame_time_secs)
                    .round() as u32)
                    .min(max_delay_frames);
                let end = match (opts.match_directions, s_end) {
                    (true, Some(e)) => e.0,
                    _ => NO_END,
                };
                links.push(Link {
                    input: sref.input,
                    bone: s.0,
                    end,
                    weight: sref.weight / total,
                    offset,
                    delay_frames,
                });
            }
            plan.num_links = links.len() as u32 - first_link;
            bones.push(plan);
        }

        let root = root_pair.map(|(rt, rs)| {
            let input = rs.input as usize;
            RootPlan::new(
                Side {
                    skel: sources[input],
                    worlds: &src_w[input],
                    eps: src_eps[input],
                },
                Side {
                    skel: target,
                    worlds: &tgt_w,
                    eps: tgt_eps,
                },
                table,
                rt,
                rs,
                opts,
            )
        });

        let history = sources
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let longest = links
                    .iter()
                    .filter(|l| l.input as usize == i)
                    .map(|l| l.delay_frames as usize)
                    .max()
                    .unwrap_or(0);
                History::new(s.num_bones(), longest + 1)
            })
            .collect();

        let mut mapping = Mapping {
            sources: sources.iter().map(|s| (*s).clone()).collect(),
            target: target.clone(),
            bones,
            links,
            root,
            history,
            scratch: vec![WorldTransform::IDENTITY; target.num_bones()],
        };
        // The aligned rest: what the target shows while every source holds its reference.
        let refs: Vec<&Pose> = src_ref.iter().collect();
        let mut aligned = target.rest_pose();
        mapping.solve(&refs, &mut aligned, false);
        for (plan, q) in mapping.bones.iter_mut().zip(&aligned.rotations) {
            plan.aligned_local = *q;
        }
        mapping.reset();
        Ok(mapping)
    }

    /// Retargets one frame: `sources[i]` is the current pose of input `i`; writes every bone of
    /// `out` (a pose of the target skeleton). Allocates nothing. Errors only when the poses do
    /// not fit the skeletons this mapping was built for.
    pub fn apply(&mut self, sources: &[&Pose], out: &mut Pose) -> Result<(), RetargetError> {
        if sources.len() != self.sources.len() {
            return Err(RetargetError::PoseSizeMismatch {
                expected: self.sources.len(),
                got: sources.len(),
            });
        }
        for (pose, skel) in sources.iter().zip(&self.sources) {
            pose.check(skel)?;
        }
        out.check(&self.target)?;
        self.solve(sources, out, true);
        Ok(())
    }

    /// [`Mapping::apply`] for a mapping with a single source input.
    pub fn apply_one(&mut self, source: &Pose, out: &mut Pose) -> Result<(), RetargetError> {
        self.apply(&[source], out)
    }

    /// Forgets the delay history (e.g. after a source restarts or seeks).
    pub fn reset(&mut self) {
        for h in &mut self.history {
            h.reset();
        }
        if let Some(root) = self.root.as_mut() {
            root.vertical_offset = None;
        }
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
    /// rest re-posed into the source's posture (e.g. an A-pose character shown in T-pose).
    pub fn aligned_rest_pose(&self) -> Pose {
        let mut p = self.target.rest_pose();
        for (r, plan) in p.rotations.iter_mut().zip(&self.bones) {
            *r = plan.aligned_local;
        }
        p
    }

    /// The target bone that receives root motion (the shallowest mapped one, normally the hips).
    pub fn root_bone(&self) -> Option<BoneId> {
        self.root.as_ref().map(|r| r.bone)
    }

    /// Target / source hip-height ratio applied to root translation.
    pub fn root_scale(&self) -> Option<f32> {
        self.root.as_ref().map(|r| r.scale)
    }

    /// The source's floor over a clip of the root input: the lowest height its foot joints
    /// reach (where they stand when planted). `None` without root motion or frames. Offline
    /// helper (allocates); pass the result to [`Mapping::set_source_floor_y`].
    pub fn measure_source_floor(&self, poses: &[Pose]) -> Option<f32> {
        let root = self.root.as_ref()?;
        let skel = self.sources.get(root.input as usize)?;
        let mut worlds = vec![WorldTransform::IDENTITY; skel.num_bones()];
        let mut lowest = f32::INFINITY;
        for p in poses {
            if p.check(skel).is_err() {
                continue;
            }
            crate::fk::forward_kinematics(skel, p, &mut worlds);
            for b in &root.contact_bones {
                lowest = lowest.min(worlds[b.index()].translation.y);
            }
        }
        lowest.is_finite().then_some(lowest)
    }

    /// Sets the source floor height (see [`RetargetOptions::source_floor_y`]).
    pub fn set_source_floor_y(&mut self, y: f32) {
        if let Some(r) = self.root.as_mut() {
            r.source_floor_y = y;
            r.vertical_offset = None;
        }
    }

    /// Number of target bones driven by at least one source bone.
    pub fn num_mapped(&self) -> usize {
        self.bones.iter().filter(|b| b.num_links > 0).count()
    }

    /// The per-frame work, shared by `apply` and by `build` (which computes the aligned rest).
    fn solve(&mut self, sources: &[&Pose], out: &mut Pose, with_options: bool) {
        for ((h, skel), pose) in self.history.iter_mut().zip(&self.sources).zip(sources) {
            h.push(skel, pose);
        }
        let parents = self.target.parents();
        let rest = self.target.rest();
        for t in 0..self.bones.len() {
            let parent = match parents[t] {
                Some(p) => self.scratch[p.index()],
                None => WorldTransform::IDENTITY,
            };
            let plan = &self.bones[t];
            let (local, world_rotation) = if plan.num_links == 0 {
                (plan.rest_local, parent.rotation * plan.rest_local)
            } else {
                let first = plan.first_link as usize;
                let mut blended = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
                let mut reference = Quat::IDENTITY;
                for (k, link) in self.links[first..first + plan.num_links as usize]
                    .iter()
                    .enumerate()
                {
                    let worlds = self.history[link.input as usize].get(link.delay_frames as usize);
                    let ws = worlds[link.bone as usize];
                    let mut q = ws.rotation * link.offset;
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
                let world = blended.normalize();
                ((parent.rotation.inverse() * world).normalize(), world)
            };
            let mut translation = rest[t].translation;
            let mut position = parent.translation + parent.rotation * translation;
            if let Some(root) = self.root.as_ref().filter(|r| r.bone.index() == t) {
                let src =
                    self.history[root.input as usize].get(0)[root.source_bone.index()].translation;
                let s = root.scale;
                let floor_t = root.target_floor_y.unwrap_or(s * root.source_floor_y);
                let y = floor_t + s * (src.y - root.source_floor_y);
                position = match root.motion {
                    RootMotion::Scaled => Vec3::new(s * src.x, y, s * src.z),
                    RootMotion::InPlace => {
                        Vec3::new(root.reference_position.x, y, root.reference_position.z)
                    }
                    RootMotion::Fixed => root.reference_position,
                };
                translation = parent.rotation.inverse() * (position - parent.translation);
            }
            self.scratch[t] = WorldTransform {
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
        self.place_feet(out);
    }

    /// Moves the root vertically so the lowest foot joint stands as high above the target's
    /// floor as the source's stands above its floor (scaled): the legs' own geometry then sets
    /// the hips height, so different proportions neither float nor sink.
    fn place_feet(&mut self, out: &mut Pose) {
        let Some(root) = self.root.as_ref() else {
            return;
        };
        if root.foot_contact == FootContact::Off
            || root.motion == RootMotion::Fixed
            || root.contacts.is_empty()
        {
            return;
        }
        let dy = match (root.foot_contact, root.vertical_offset) {
            (FootContact::FirstFrame, Some(dy)) => dy,
            _ => {
                let dy = self.foot_offset();
                if let Some(root) = self.root.as_mut() {
                    root.vertical_offset = Some(dy);
                }
                dy
            }
        };
        let Some(root) = self.root.as_ref() else {
            return;
        };
        let parent_rotation = match self.target.parent(root.bone) {
            Some(p) => self.scratch[p.index()].rotation,
            None => Quat::IDENTITY,
        };
        out.translations[root.bone.index()] += parent_rotation.inverse() * Vec3::new(0.0, dy, 0.0);
    }

    /// The vertical move that puts the target's lowest foot joint at the scaled source height.
    fn foot_offset(&self) -> f32 {
        let Some(root) = self.root.as_ref() else {
            return 0.0;
        };
        let src = self.history[root.input as usize].get(0);
        let scale = root.scale;
        let floor_t = root.target_floor_y.unwrap_or(scale * root.source_floor_y);
        let mut lowest_s = [f32::INFINITY; MAX_LEGS];
        let mut lowest_t = [f32::INFINITY; MAX_LEGS];
        for &(t, s, leg) in &root.contacts {
            let leg = leg as usize;
            lowest_s[leg] = lowest_s[leg].min(src[s.index()].translation.y);
            lowest_t[leg] = lowest_t[leg].min(self.scratch[t.index()].translation.y);
        }
        let error =
            |leg: usize| floor_t + scale * (lowest_s[leg] - root.source_floor_y) - lowest_t[leg];
        let legs = (0..MAX_LEGS).filter(|&l| lowest_t[l].is_finite());
        if root.foot_contact == FootContact::EveryFrame {
            // The lowest foot carries the weight: it decides.
            let low = legs.min_by(|&a, &b| lowest_t[a].total_cmp(&lowest_t[b]));
            low.map(error).unwrap_or(0.0)
        } else {
            // One calibration for all frames: split the proportion mismatch between the feet.
            let (sum, n) = legs.fold((0.0, 0), |(sum, n), l| (sum + error(l), n + 1));
            if n > 0 {
                sum / n as f32
            } else {
                0.0
            }
        }
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

/// One skeleton in its reference posture, for build-time measurements.
#[derive(Clone, Copy)]
struct Side<'a> {
    skel: &'a Skeleton,
    worlds: &'a [WorldTransform],
    eps: f32,
}

/// The floor a reference posture stands on: its lowest foot joint when that is near y = 0 (a
/// character authored standing on the ground); unknown for a rest floating at the origin (like
/// CMU's, with the hips at y = 0).
fn floor_from_reference(lowest_y: f32, leg_height: f32) -> Option<f32> {
    (lowest_y.abs() <= 0.25 * leg_height).then_some(lowest_y)
}

impl RootPlan {
    /// Hip-height ratio from each reference posture, measured down the legs to the lowest mapped
    /// joints (averaged over both legs; falls back to the ratio of overall sizes), and floors.
    fn new(
        src: Side<'_>,
        tgt: Side<'_>,
        table: &MappingTable,
        rt: BoneId,
        rs: SourceRef,
        opts: &RetargetOptions,
    ) -> RootPlan {
        // Pairs below the root on both sides: the legs (and whatever else hangs from the hips).
        let below: Vec<(BoneId, BoneId)> = tgt
            .skel
            .bone_ids()
            .filter(|&t| t != rt && align::is_descendant(tgt.skel, rt, t))
            .filter_map(|t| {
                let s = primary(table, t)?;
                (s.input == rs.input
                    && s.bone != rs.bone
                    && align::is_descendant(src.skel, rs.bone, s.bone))
                .then_some((t, s.bone))
            })
            .collect();
        let y_t = |b: BoneId| tgt.worlds[b.index()].translation.y;
        let y_s = |b: BoneId| src.worlds[b.index()].translation.y;
        let low = below
            .iter()
            .copied()
            .min_by(|a, b| y_t(a.0).total_cmp(&y_t(b.0)));
        let mut scale = align::extent(tgt.worlds) / align::extent(src.worlds);
        let mut contacts = Vec::new();
        let (mut floor_t, mut floor_s) = (None, None);
        if let Some((tl, _)) = low {
            let first = align::leg_height(tgt.skel, tgt.worlds, rt, tl, tgt.eps);
            // Every pair at the lowest level (both feet), so left/right asymmetry averages out.
            let (mut sum_t, mut sum_s) = (0.0, 0.0);
            for &(t, s) in below
                .iter()
                .filter(|(t, _)| y_t(*t) <= y_t(tl) + 0.02 * first)
            {
                let ht = align::leg_height(tgt.skel, tgt.worlds, rt, t, tgt.eps);
                let hs = align::leg_height(src.skel, src.worlds, rs.bone, s, src.eps);
                if ht > tgt.eps && hs > src.eps {
                    sum_t += ht;
                    sum_s += hs;
                }
            }
            if sum_t > 0.0 && sum_s > 0.0 {
                scale = sum_t / sum_s;
            }
            // Feet: mapped joints near the lowest one (toes, ankles, both sides).
            let near = y_t(tl) + 0.15 * first;
            let mut legs: Vec<BoneId> = Vec::new();
            contacts = below
                .iter()
                .copied()
                .filter(|(t, _)| y_t(*t) <= near)
                .map(|(t, s)| {
                    // The leg: the root's child this joint hangs from.
                    let mut top = t;
                    while let Some(p) = tgt.skel.parent(top).filter(|&p| p != rt) {
                        top = p;
                    }
                    let leg = legs.iter().position(|&l| l == top).unwrap_or_else(|| {
                        legs.push(top);
                        legs.len() - 1
                    });
                    (t, s, leg.min(MAX_LEGS - 1) as u8)
                })
                .collect();
            let lowest_s = contacts
                .iter()
                .map(|&(_, b, _)| y_s(b))
                .fold(f32::INFINITY, f32::min);
            floor_t = floor_from_reference(y_t(tl), first);
            floor_s = floor_from_reference(lowest_s, first / scale);
        }
        RootPlan {
            bone: rt,
            input: rs.input,
            source_bone: rs.bone,
            scale: opts.root_scale.unwrap_or(scale),
            motion: opts.root_motion,
            source_floor_y: opts.source_floor_y.or(floor_s).unwrap_or(0.0),
            target_floor_y: opts.target_floor_y.or(floor_t),
            reference_position: tgt.worlds[rt.index()].translation,
            contact_bones: contacts.iter().map(|&(_, s, _)| s).collect(),
            contacts,
            foot_contact: opts.foot_contact,
            vertical_offset: None,
        }
    }
}
