//! The idle fallback: a motion graph a performer's character walks on while its source is
//! lost, so it keeps breathing or idling instead of freezing.
//!
//! ```text
//!  at start (the host reads the files):  .rmg + its clips ─▶ clips on one rig (clip 0's) ─▶ Playback
//!                        rig → character mapping, character → rig mapping (auto, both ways)
//!  source lost:          shown pose ─to rig─▶ nearest node (the graph's own posture distance)
//!  every tick:           Walker steps by the tick's time ─▶ rig pose ─map─▶ character pose
//!                        ─▶ turned and placed so its heading continues the pose at the loss
//! ```
//!
//! The walk stays where the source was lost, facing the same way (the graph's heading frame
//! — the floor under the hips, the way hips and shoulders face — is pinned to the one at the
//! loss): an idle graph hardly travels or turns, and a locomotion graph walks on the spot, so
//! handing back to live motion where the performer stands never has to cover the distance
//! walked, or turn the whole body round, within the short resume blend. Everything
//! per tick writes into buffers sized here: no allocation.

use std::sync::Arc;

use glam::Vec3;
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::fk::WorldTransform;
use rigcast_retarget::graph::play::clips_onto_rig;
use rigcast_retarget::graph::{BodyPoints, MotionGraph, Planar, Playback, Walker};
use rigcast_retarget::mapping::{auto_map, MapOptions};
use rigcast_retarget::{BoneId, Clip, Mapping, Pose, RetargetOptions, Skeleton};

use crate::error::{failed, PrepareError, PrepareResult};

/// Seed of the fallback's wandering (fixed: a run can be reproduced).
const WANDER_SEED: u64 = 0x1d1e;

/// Most graph frames one tick advances (a stalled tick skips ahead instead of replaying).
const MAX_STEPS_PER_TICK: usize = 16;

/// A performer's idle graph, ready for the tick.
pub struct IdleGraph {
    playback: Playback,
    walker: Walker,
    /// The graph's rig → the character.
    to_target: Mapping,
    /// The character → the graph's rig (finds the node nearest the pose at the loss).
    from_target: Mapping,
    /// Scratch pose on the graph's rig.
    rig_pose: Pose,
    rig_worlds: Vec<WorldTransform>,
    target: Arc<Skeleton>,
    target_body: BodyPoints,
    target_roots: Vec<BoneId>,
    target_worlds: Vec<WorldTransform>,
    /// The heading's yaw at the loss, kept while walking.
    facing: f32,
    /// Where the heading origin stays (the floor under the hips at the loss).
    spot: Vec3,
    /// Graph time not yet stepped, seconds.
    pending_secs: f64,
    /// The graph's cross-fade, seconds: the take-over blends in over as long.
    blend_secs: f32,
}

impl IdleGraph {
    /// Prepares `graph` (with its `clips`, as read) for playing on `target`.
    pub fn new(
        graph: &MotionGraph,
        clips: &[Clip],
        target: &Arc<Skeleton>,
        target_reference: Option<&Pose>,
        tick_secs: f32,
    ) -> PrepareResult<IdleGraph> {
        let rig = clips
            .first()
            .ok_or_else(|| PrepareError::new("the graph has no clips"))?;
        let rig_analysis = analyze(&SkeletonView::from_clip(&rig.skeleton, &rig.poses));
        let played = clips_onto_rig(clips, rig).map_err(|e| PrepareError::new(e.to_string()))?;
        let playback = Playback::new(graph, &played, &rig_analysis)
            .map_err(|e| PrepareError::new(e.to_string()))?;
        let target_view = SkeletonView::with_pose(target, target_reference);
        let target_analysis = analyze(&target_view);
        let target_body = BodyPoints::find(&target_analysis)
            .map_err(failed("the character cannot walk a motion graph"))?;
        let rig_view = SkeletonView::from_clip(&rig.skeleton, &rig.poses);
        let options = |reference: Option<Pose>, up: Vec3| RetargetOptions {
            frame_time_secs: tick_secs,
            source_reference: vec![reference],
            source_up: Some(up),
            ..RetargetOptions::default()
        };
        let rig_reference = rig_analysis.posture_pose(&rig.poses);
        let table = auto_map(&rig_view, &target_view, &MapOptions::default());
        let mut to_target = Mapping::build(
            &[&rig.skeleton],
            target,
            &table,
            &options(
                rig_reference.filter(|_| rig_analysis.used_pose),
                rig_analysis.up,
            ),
        )
        .map_err(failed("cannot map the graph's rig onto the character"))?;
        if let Some(floor) = to_target.measure_source_floor(&rig.poses) {
            to_target.set_source_floor_y(floor);
        }
        let back = auto_map(&target_view, &rig_view, &MapOptions::default());
        let from_target = Mapping::build(
            &[target],
            &rig.skeleton,
            &back,
            &options(target_reference.cloned(), target_analysis.up),
        )
        .map_err(failed("cannot map the character onto the graph's rig"))?;
        let walker = Walker::new(graph, &playback, WANDER_SEED);
        Ok(IdleGraph {
            rig_pose: rig.skeleton.rest_pose(),
            rig_worlds: vec![WorldTransform::IDENTITY; rig.skeleton.num_bones()],
            target: target.clone(),
            target_body,
            target_roots: target.roots().collect(),
            target_worlds: vec![WorldTransform::IDENTITY; target.num_bones()],
            facing: 0.0,
            spot: Vec3::ZERO,
            pending_secs: 0.0,
            blend_secs: graph.settings.blend_secs.max(0.0),
            playback,
            walker,
            to_target,
            from_target,
        })
    }

    /// Seconds the take-over should blend in over (the graph's own cross-fade).
    pub fn blend_secs(&self) -> f32 {
        self.blend_secs
    }

    /// Restricts the walk to the clips `allowed` marks (one flag per clip of the graph).
    pub fn allow_clips(&mut self, allowed: &[bool]) {
        self.walker.set_allowed_clips(allowed);
    }

    /// The node the walker is at.
    pub fn node(&self) -> usize {
        self.walker.node()
    }

    /// Starts walking from the node nearest `shown` (the character's pose at the loss), turned
    /// and placed to continue it; writes the first pose into `out`. Allocates nothing (one
    /// pass over the nodes).
    pub fn take_over(&mut self, shown: &Pose, out: &mut Pose) {
        let node = match self.from_target.apply(&[shown], &mut self.rig_pose) {
            Ok(()) => {
                self.playback
                    .nearest(&self.rig_pose, &mut self.rig_worlds)
                    .0
            }
            Err(_) => self.walker.node(),
        };
        self.walker.start_at(node, Planar::IDENTITY);
        self.pending_secs = 0.0;
        let at_loss = self.heading(shown);
        self.walker.write(&self.playback, &mut self.rig_pose);
        // Both plans were built for these very skeletons, so `apply` cannot meet a foreign pose;
        // if it ever failed, `out` would keep the pose shown at the loss, a safe fallback.
        let _ = self.to_target.apply(&[&self.rig_pose], out);
        self.facing = at_loss.yaw;
        self.spot = at_loss.offset;
        self.place(out);
    }

    /// Moves on by `secs` of graph time and writes the character's pose into `out`.
    /// Allocates nothing.
    pub fn advance(&mut self, secs: f64, out: &mut Pose) {
        let frame = self.playback.frame_time_secs();
        self.pending_secs += secs.max(0.0);
        let mut steps = 0;
        while self.pending_secs >= frame && steps < MAX_STEPS_PER_TICK {
            self.walker.step(&self.playback, &mut self.rig_pose);
            self.pending_secs -= frame;
            steps += 1;
        }
        // A long stall: drop the rest rather than catching up over many ticks.
        self.pending_secs = self.pending_secs.min(frame);
        if steps == 0 {
            self.walker.write(&self.playback, &mut self.rig_pose);
        }
        if self.to_target.apply(&[&self.rig_pose], out).is_ok() {
            self.place(out);
        }
    }

    /// The heading frame of a character pose (the floor under the hips, the way it faces).
    pub fn heading(&mut self, pose: &Pose) -> Planar {
        let p = self
            .target_body
            .points(&self.target, pose, &mut self.target_worlds);
        self.target_body.heading(&p)
    }

    /// Puts `out`'s heading frame where the character stood at the loss: same spot, same
    /// facing.
    fn place(&mut self, out: &mut Pose) {
        let up = self.target_body.up();
        let h = self.heading(out);
        let turn = Planar {
            yaw: self.facing - h.yaw,
            offset: Vec3::ZERO,
        };
        let align = Planar {
            yaw: turn.yaw,
            offset: self.spot - turn.apply(up, h.offset),
        };
        let q = align.rotation(up);
        for r in &self.target_roots {
            let i = r.index();
            out.rotations[i] = (q * out.rotations[i]).normalize();
            out.translations[i] = align.apply(up, out.translations[i]);
        }
    }
}
