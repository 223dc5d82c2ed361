//! The tick side of a performer: source subject(s) → [`Mapping::apply`] → target subject, with
//! easing when a source is lost and when it comes back.
//!
//! ```text
//!  sources' latest poses ─copy─▶ inputs (preallocated) ─apply─▶ foot lock ─▶ live ─┐
//!                                                                     ├─ blend ─▶ display ─▶ target slot
//!  source lost:  from = display at loss ──slerp (0.5 s)──▶ the character's own rest, where it
//!                stands; or hold `from`; or (idle graph) from ──blend (the graph's
//!                cross-fade time) onto a walk on the graph from the nearest node (`idle_graph`)
//!  source back:  from = display at return ──blend onto the moving live pose, each bone
//!                turning one way (0.2 s; 0.3 s after an idle graph; `resume_secs`)──▶ live
//! ```
//!
//! Mappings are built off the tick (by the host's mapper) and handed over through a mailbox the tick
//! polls with `try_lock`, so a rebuild never stalls a tick. Every buffer is sized when a
//! mapping arrives; steady-state ticks allocate nothing.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rigcast_protocol::{SourceState, TargetMotion};
use rigcast_retarget::footplant::FootLock;
use rigcast_retarget::{Mapping, Pose};

use crate::clock::TickTime;
use crate::graft_live::{LiveGraft, LockTiming};
use crate::idle_graph::IdleGraph;
use crate::settings::OnLost;
use crate::slot::FrameWriter;
use crate::subject::Subject;

/// Time to ease to rest after a loss.
pub const EASE_OUT: Duration = Duration::from_millis(500);
/// Time to ease back in after a return.
pub const EASE_IN: Duration = Duration::from_millis(200);
/// Time to blend back from an idle graph to live motion (unless configured).
pub const IDLE_RESUME: Duration = Duration::from_millis(300);
/// Most source subjects one target can blend (keeps the per-tick input list on the stack).
pub const MAX_INPUTS: usize = 8;

/// A mapping ready for the tick.
#[derive(Debug)]
pub struct BuiltMapping {
    /// The job.
    pub mapping: Mapping,
    /// Pins the target's feet while the source's are planted (`None`: off, or nothing to
    /// lock on this character). For a graft, on the lower body's plants.
    pub foot_lock: Option<FootLock>,
    /// A graft: `mapping` then drives the upper body from input 0, this the lower body (from
    /// input 1, or its looping clip) and the splice.
    pub graft: Option<LiveGraft>,
}

/// Longest gap between two source samples the plant detector treats as continuous motion.
const MAX_SAMPLE_GAP_SECS: f32 = 0.25;

/// Where the built mappings of one performer are handed to the tick.
pub type Mailbox = Arc<Mutex<Option<BuiltMapping>>>;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Live,
    Resuming(Instant),
    Lost(Instant),
}

/// One performer as the tick runs it.
pub struct Performer {
    /// The target subject.
    pub target: Arc<Subject>,
    tx: FrameWriter,
    sources: Vec<Arc<Subject>>,
    mailbox: Mailbox,
    current: Option<BuiltMapping>,
    inputs: Vec<Pose>,
    live: Pose,
    from: Pose,
    display: Pose,
    /// The target skeleton's own rest pose.
    rest: Pose,
    /// Where a lost target eases to: its rest, standing where it was (see [`rest_in_place`]).
    settle: Pose,
    phase: Phase,
    on_lost: OnLost,
    /// The graph walked while the source is lost (with [`OnLost::Idle`]).
    idle: Option<IdleGraph>,
    /// How long the blend back to live takes.
    resume: Duration,
    /// Each bone's difference from `from` in the last blend (see [`blend_onto`]).
    turns: Pose,
    /// The next blend is the first since `from` was taken.
    blend_fresh: bool,
    last_input_seqs: [u64; MAX_INPUTS],
    /// Capture time of the foot lock's source input at its last sample.
    last_lock_capture: u64,
    /// When the previous tick ran (a graft's looping clip moves on by the time between).
    last_tick: Option<Instant>,
    seq: u64,
    published: bool,
    /// The eased-to pose has been published (nothing changes until the source returns).
    settled: bool,
    /// A fault is being reported on the target (see [`crate::fault`]).
    faulted: bool,
    /// While faulted, when to try again.
    retry_at: Option<Instant>,
}

/// The character's own rest pose (not the source's rest retargeted, which for a T-pose source
/// and an A-pose character is neither), standing where `from` left it: every bone takes its
/// rest rotation and its rest height, but keeps its horizontal translation, so a character that
/// walked away from the origin settles on the spot instead of sliding back. No allocation.
fn rest_in_place(rest: &Pose, from: &Pose, out: &mut Pose) {
    out.copy_from(rest);
    for (t, f) in out.translations.iter_mut().zip(&from.translations) {
        t.x = f.x;
        t.z = f.z;
    }
}

/// Publishes which of the target's feet the lock holds (a bitmask for the status API).
fn store_held_feet(target: &Subject, lock: &FootLock) {
    let held = (0..lock.target_legs().count().min(32))
        .filter(|&i| lock.is_locked(i))
        .fold(0u32, |bits, i| bits | 1 << i);
    target
        .stats
        .feet_locked
        .store(held, std::sync::atomic::Ordering::Relaxed);
}

/// Writes `onto` with `1 − k` of its per-bone difference from `from` on top: rotations
/// `part(from · onto⁻¹, 1 − k) · onto`, translations lerped. `turns` holds each bone's
/// difference of the previous call (`fresh`: none yet, start on the short arc); keeping each
/// difference's sign continuous with it means a bone whose difference passes 180° as `onto`
/// moves keeps turning the same way, where a plain slerp between the poses would flip to the
/// other short arc in one frame. No allocation.
fn blend_onto(from: &Pose, onto: &Pose, k: f32, turns: &mut Pose, fresh: bool, out: &mut Pose) {
    let keep = 1.0 - k;
    let bones = out
        .rotations
        .iter_mut()
        .zip(&from.rotations)
        .zip(&onto.rotations);
    for (((r, f), o), prev) in bones.zip(&mut turns.rotations) {
        let mut d = (*f * o.inverse()).normalize();
        let flip = if fresh { d.w < 0.0 } else { d.dot(*prev) < 0.0 };
        if flip {
            d = -d;
        }
        *prev = d;
        *r = (part_of_turn(d, keep) * *o).normalize();
    }
    let moves = out
        .translations
        .iter_mut()
        .zip(&from.translations)
        .zip(&onto.translations);
    for ((t, f), o) in moves {
        *t = o.lerp(*f, keep);
    }
}

/// The fraction `s` of the turn `q` taken the way `q` goes (its angle may exceed 180°, unlike
/// a slerp from identity, which takes the short arc).
fn part_of_turn(q: glam::Quat, s: f32) -> glam::Quat {
    let v = glam::Vec3::new(q.x, q.y, q.z);
    let half = v.length().atan2(q.w);
    let Some(axis) = v.try_normalize() else {
        return glam::Quat::IDENTITY;
    };
    let (sin, cos) = (half * s).sin_cos();
    glam::Quat::from_xyzw(axis.x * sin, axis.y * sin, axis.z * sin, cos)
}

/// Smooth 0→1 ramp with zero slope at both ends (no jump when easing starts or ends).
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl Performer {
    /// A performer writing into `tx` (the target subject's slot).
    pub fn new(
        target: Arc<Subject>,
        tx: FrameWriter,
        sources: Vec<Arc<Subject>>,
        mailbox: Mailbox,
        on_lost: OnLost,
    ) -> Performer {
        let rest = target.skeleton().rest_pose();
        Performer {
            target,
            tx,
            sources,
            mailbox,
            current: None,
            inputs: Vec::new(),
            live: rest.clone(),
            turns: rest.clone(),
            from: rest.clone(),
            display: rest.clone(),
            settle: rest.clone(),
            rest,
            phase: Phase::Live,
            on_lost,
            idle: None,
            resume: EASE_IN,
            blend_fresh: true,
            last_input_seqs: [0; MAX_INPUTS],
            last_lock_capture: 0,
            last_tick: None,
            seq: 0,
            published: false,
            settled: false,
            faulted: false,
            retry_at: None,
        }
    }

    /// Walks `idle` while the source is lost (with [`OnLost::Idle`]) and blends back to live
    /// over `resume` (default [`IDLE_RESUME`]).
    pub fn with_idle_graph(mut self, idle: IdleGraph, resume: Option<Duration>) -> Performer {
        self.idle = Some(idle);
        self.resume = resume.unwrap_or(IDLE_RESUME);
        self
    }

    /// Blends back to live over `resume` when the source returns.
    pub fn with_resume(mut self, resume: Duration) -> Performer {
        self.resume = resume;
        self
    }

    /// Hands over a newly built mapping (the next tick takes it), replacing one not yet
    /// taken.
    pub fn offer(&self, built: BuiltMapping) {
        let mut slot = self.mailbox.lock().unwrap_or_else(|p| p.into_inner());
        *slot = Some(built);
    }

    fn take_new_mapping(&mut self) {
        let Ok(mut slot) = self.mailbox.try_lock() else {
            return;
        };
        let Some(mut built) = slot.take() else { return };
        drop(slot);
        // Rare (a rebuild): size the input copies for the new source skeletons (a graft's
        // lower source is the last input).
        self.inputs = (0..built.mapping.num_inputs())
            .filter_map(|i| built.mapping.source(i).map(|s| s.rest_pose()))
            .collect();
        if let Some(g) = built.graft.as_mut() {
            if g.gait.is_none() {
                self.inputs
                    .extend(g.lower_mapping.source(0).map(|s| s.rest_pose()));
            }
            // The looping clip keeps its phase across a re-map.
            if let Some(old) = self.current.as_mut().and_then(|c| c.graft.as_mut()) {
                g.continue_from(old);
            }
        }
        self.current = Some(built);
    }

    /// Runs one tick: read the sources, follow them (or fall back while they are lost), publish.
    /// Allocates nothing in steady state. A panic in its processing, or a pose that comes out
    /// not finite, is caught here and faults this performer alone (see [`Performer::fault`]):
    /// the tick and the other performers go on. Reads no clock: `time` is the tick's.
    pub fn tick(&mut self, time: TickTime) {
        let now = time.instant;
        self.take_new_mapping();
        if self.retry_at.is_some_and(|t| now < t) {
            return;
        }
        let tick_secs = self
            .last_tick
            .map(|t| now.saturating_duration_since(t).as_secs_f64())
            .unwrap_or(0.0)
            .min(f64::from(MAX_SAMPLE_GAP_SECS));
        self.last_tick = Some(now);
        // Taken out for the tick (a move, no allocation) so the steps below can borrow `self`.
        let Some(mut built) = self.current.take() else {
            return;
        };
        let shown = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            self.step(&mut built, time, tick_secs)
        }));
        match shown {
            Ok(Some((moving, capture))) => match self.display.check_values() {
                Ok(_) => {
                    self.publish(moving, capture, now);
                    self.clear_fault();
                }
                Err(r) => {
                    let why = format!("its pose came out wrong at bone {}: {}", r.bone, r.fault);
                    self.fault(&mut built, now, why);
                }
            },
            Ok(None) => {}
            Err(payload) => {
                let why = format!("stopped: {}", crate::fault::panic_text(&*payload));
                self.fault(&mut built, now, why);
            }
        }
        self.current = Some(built);
    }

    /// Records a fault on the target (once per episode), starts the performer afresh from its
    /// character's rest (its blends and the mapping's and foot lock's state may hold the bad
    /// values) and waits [`crate::fault::FAULT_RETRY`] before trying again. The last good
    /// pose stays published meanwhile.
    fn fault(&mut self, built: &mut BuiltMapping, now: Instant, why: String) {
        built.mapping.reset();
        if let Some(lock) = built.foot_lock.as_mut() {
            lock.reset();
        }
        for pose in [
            &mut self.live,
            &mut self.from,
            &mut self.display,
            &mut self.turns,
        ] {
            pose.copy_from(&self.rest);
        }
        self.phase = Phase::Live;
        self.blend_fresh = true;
        self.retry_at = Some(now + crate::fault::FAULT_RETRY);
        if !self.faulted {
            self.faulted = true;
            let stats = &self.target.stats;
            stats
                .faults_total
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            tracing::error!("target {}: {why}", self.target.info().name);
            if let Ok(mut f) = stats.fault.lock() {
                *f = Some(why);
            }
        }
    }

    /// Ends a fault episode once a tick ran through and published a sane pose.
    fn clear_fault(&mut self) {
        self.retry_at = None;
        if self.faulted {
            self.faulted = false;
            tracing::info!("target {}: running again", self.target.info().name);
            if let Ok(mut f) = self.target.stats.fault.lock() {
                *f = None;
            }
        }
    }

    /// One tick's pose into `display`: whether it changed and the capture time to stamp it
    /// with, or `None` when there is nothing to show yet.
    fn step(
        &mut self,
        built: &mut BuiltMapping,
        time: TickTime,
        tick_secs: f64,
    ) -> Option<(bool, u64)> {
        let now = time.instant;
        let read = self.read_inputs()?;
        self.change_phase(built, read.lost, now);
        let moving = match self.phase {
            Phase::Lost(t0) => self.fall_back(now.duration_since(t0), tick_secs),
            Phase::Live | Phase::Resuming(_) => {
                self.follow_live(built, &read, tick_secs)?;
                self.blend_in(now)
                    || read.changed
                    || built.graft.as_ref().is_some_and(|g| g.gait.is_some())
            }
        };
        self.target.stats.motion.store(self.motion());
        let capture = match self.phase {
            // Nothing captured it: the fallback's pose is made now.
            Phase::Lost(_) => time.unix_nanos,
            _ => read.newest_capture,
        };
        Some((moving, capture))
    }

    /// Copies the sources' latest poses; `None` until every source has produced a pose that
    /// fits the mapping (after a skeleton change the rebuild is on its way).
    fn read_inputs(&mut self) -> Option<InputRead> {
        let n = self.inputs.len().min(MAX_INPUTS);
        if n == 0 || n != self.sources.len() {
            return None;
        }
        let mut read = InputRead {
            newest_capture: 0,
            changed: false,
            captures: [0; MAX_INPUTS],
            lost: false,
        };
        for (i, (src, copy)) in self.sources.iter().zip(&mut self.inputs).enumerate() {
            let frame = src.latest.borrow();
            if frame.capture_nanos == 0 || frame.pose.num_bones() != copy.num_bones() {
                return None;
            }
            copy.copy_from(&frame.pose);
            read.captures[i] = frame.capture_nanos;
            read.newest_capture = read.newest_capture.max(frame.capture_nanos);
            if frame.seq != self.last_input_seqs[i] {
                self.last_input_seqs[i] = frame.seq;
                read.changed = true;
            }
            read.lost |= src.health.state() == SourceState::Lost;
        }
        Some(read)
    }

    /// Starts the fallback when a source is lost, the blend back when it returns.
    fn change_phase(&mut self, built: &mut BuiltMapping, lost: bool, now: Instant) {
        match (self.phase, lost) {
            (Phase::Live | Phase::Resuming(_), true) => {
                self.from.copy_from(&self.display);
                rest_in_place(&self.rest, &self.from, &mut self.settle);
                if let (OnLost::Idle, Some(idle)) = (self.on_lost, self.idle.as_mut()) {
                    idle.take_over(&self.from, &mut self.settle);
                    self.blend_fresh = true;
                }
                self.phase = Phase::Lost(now);
                self.settled = false;
            }
            (Phase::Lost(_), false) => {
                self.from.copy_from(&self.display);
                self.phase = Phase::Resuming(now);
                self.blend_fresh = true;
                // The motion seen before the loss says nothing about the feet now.
                if let Some(lock) = built.foot_lock.as_mut() {
                    lock.reset();
                }
            }
            _ => {}
        }
    }

    /// The pose while the source is lost, `since` the loss; whether it changed.
    fn fall_back(&mut self, since: Duration, tick_secs: f64) -> bool {
        let secs = since.as_secs_f32();
        match (self.on_lost, self.idle.as_mut()) {
            (OnLost::Idle, Some(idle)) => {
                // Blend from the pose at the loss onto the walk as it moves on.
                let k = smoothstep(secs / idle.blend_secs().max(1e-3));
                idle.advance(tick_secs, &mut self.settle);
                let fresh = std::mem::take(&mut self.blend_fresh);
                blend_onto(
                    &self.from,
                    &self.settle,
                    k,
                    &mut self.turns,
                    fresh,
                    &mut self.display,
                );
                true
            }
            (OnLost::Hold, _) => {
                self.display.copy_from(&self.from);
                let moving = !self.settled;
                self.settled = true;
                moving
            }
            // Ease (and an idle performer whose graph did not load: validated at start).
            _ => {
                let k = smoothstep(secs / EASE_OUT.as_secs_f32());
                self.display.interpolate_into(&self.from, &self.settle, k);
                // Publish up to and including the frame that reaches rest.
                let moving = !self.settled;
                self.settled = k >= 1.0;
                moving
            }
        }
    }

    /// Retargets the inputs into `live` (graft or plain, then the foot lock); `None` when the
    /// poses do not fit the mapping.
    fn follow_live(
        &mut self,
        built: &mut BuiltMapping,
        read: &InputRead,
        tick_secs: f64,
    ) -> Option<()> {
        let n = self.inputs.len().min(MAX_INPUTS);
        if let Some(g) = built.graft.as_mut() {
            let timing = match g.gait {
                Some(_) => LockTiming {
                    fresh: true,
                    dt_secs: tick_secs as f32,
                },
                None => self.lock_timing(read.captures[n - 1]),
            };
            let lower = (n > 1).then(|| &self.inputs[n - 1]);
            let lock = built.foot_lock.as_mut().map(|l| (l, timing));
            if !g.apply(
                &mut built.mapping,
                &self.inputs[0],
                lower,
                tick_secs,
                lock,
                &mut self.live,
            ) {
                return None;
            }
            if let Some(lock) = built.foot_lock.as_ref() {
                store_held_feet(&self.target, lock);
            }
            return Some(());
        }
        let mut refs: [&Pose; MAX_INPUTS] = [&self.inputs[0]; MAX_INPUTS];
        for (r, p) in refs.iter_mut().zip(&self.inputs) {
            *r = p;
        }
        built.mapping.apply(&refs[..n], &mut self.live).ok()?;
        if let Some(lock) = built.foot_lock.as_mut() {
            let input = built.mapping.root_input().unwrap_or(0).min(n - 1);
            let timing = self.lock_timing(read.captures[input]);
            lock.apply_live(
                &self.inputs[input],
                timing.fresh,
                timing.dt_secs,
                &mut self.live,
            );
            store_held_feet(&self.target, lock);
        }
        Some(())
    }

    /// Whether the foot lock's input has a new sample, and the time since its previous one.
    fn lock_timing(&mut self, capture: u64) -> LockTiming {
        let fresh = capture != self.last_lock_capture;
        let dt = capture.saturating_sub(self.last_lock_capture) as f32 * 1e-9;
        self.last_lock_capture = capture;
        LockTiming {
            fresh,
            dt_secs: dt.min(MAX_SAMPLE_GAP_SECS),
        }
    }

    /// `live` into `display`, blended in from the fallback while resuming; whether it blends.
    fn blend_in(&mut self, now: Instant) -> bool {
        let Phase::Resuming(t0) = self.phase else {
            self.display.copy_from(&self.live);
            return false;
        };
        let k =
            smoothstep(now.duration_since(t0).as_secs_f32() / self.resume.as_secs_f32().max(1e-3));
        // Onto the moving live pose, each bone turning one way: an idle graph's arm can stand
        // near 180° from the performer's, and a plain slerp would flip to the other short arc
        // (a whole-arm swing in one frame) when the live arm crosses that line.
        let fresh = std::mem::take(&mut self.blend_fresh);
        blend_onto(
            &self.from,
            &self.live,
            k,
            &mut self.turns,
            fresh,
            &mut self.display,
        );
        if k >= 1.0 {
            self.phase = Phase::Live;
        }
        true
    }

    /// What drives the character now (for `source_status`).
    fn motion(&self) -> TargetMotion {
        match (self.phase, self.on_lost, self.idle.is_some()) {
            (Phase::Live, ..) => TargetMotion::Live,
            (Phase::Resuming(_), ..) => TargetMotion::Resuming,
            (Phase::Lost(_), OnLost::Idle, true) => TargetMotion::IdleGraph,
            (Phase::Lost(_), OnLost::Hold, _) => TargetMotion::Hold,
            (Phase::Lost(_), ..) => TargetMotion::Rest,
        }
    }

    /// Sends `display` as the target's frame, with a new seq whenever the pose changed
    /// (clients skip repeated seqs).
    fn publish(&mut self, moving: bool, capture: u64, now: Instant) {
        if !moving && self.published {
            return;
        }
        self.seq += 1;
        self.published = true;
        let seq = self.seq;
        let display = &self.display;
        self.tx.send_modify(|f| {
            if f.pose.num_bones() == display.num_bones() {
                f.pose.copy_from(display);
            }
            f.seq = seq;
            f.capture_nanos = capture;
        });
        self.target.stats.input.tick(now);
        self.target
            .stats
            .last_capture_nanos
            .store(capture, std::sync::atomic::Ordering::Relaxed);
        // When the newest input pose was handed to the engine (the `handoff` latency of this
        // frame; a source publishing again during this tick makes it read as no wait). A
        // fallback pose (source lost) is made by the tick itself: not timed (0).
        let published = match self.phase {
            Phase::Lost(_) => 0,
            _ => (self.sources.iter())
                .map(|s| {
                    s.stats
                        .published_nanos
                        .load(std::sync::atomic::Ordering::Relaxed)
                })
                .max()
                .unwrap_or(0),
        };
        self.target
            .stats
            .published_nanos
            .store(published, std::sync::atomic::Ordering::Relaxed);
    }
}

/// What one tick read from the sources.
struct InputRead {
    newest_capture: u64,
    changed: bool,
    captures: [u64; MAX_INPUTS],
    lost: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};

    fn one_bone(q: Quat) -> Pose {
        Pose {
            rotations: vec![q],
            translations: vec![Vec3::ZERO],
        }
    }

    /// Halfway from no turn onto a bone turning past 180° about Z: the blend is half of the
    /// turn the bone has made (85° … 95°), continuing the same way, where a slerp between
    /// the poses flips to −85° once the turn passes 180°.
    #[test]
    fn a_blend_onto_a_bone_crossing_180_degrees_keeps_turning_one_way() {
        let from = one_bone(Quat::IDENTITY);
        let mut turns = one_bone(Quat::IDENTITY);
        let mut out = one_bone(Quat::IDENTITY);
        for (i, degrees) in (170..=190).enumerate() {
            let theta = (degrees as f32).to_radians();
            let onto = one_bone(Quat::from_rotation_z(theta));
            blend_onto(&from, &onto, 0.5, &mut turns, i == 0, &mut out);
            let expected = Quat::from_rotation_z(theta * 0.5);
            let off = out.rotations[0].angle_between(expected).to_degrees();
            // 0.1°: acos near 1 in f32 resolves no finer; a flip would be 170° off.
            assert!(off < 0.1, "at {degrees}°: {off}° off half the turn");
        }
    }

    /// The first blend takes the short arc, as a slerp between the two poses does.
    #[test]
    fn a_fresh_blend_matches_the_short_arc_slerp() {
        let from = one_bone(Quat::from_rotation_y(2.0));
        let onto = one_bone(Quat::from_rotation_x(-1.5) * Quat::from_rotation_z(0.7));
        let mut turns = one_bone(Quat::IDENTITY);
        let (mut out, mut slerped) = (from.clone(), from.clone());
        for k in [0.0, 0.3, 0.8, 1.0] {
            blend_onto(&from, &onto, k, &mut turns, true, &mut out);
            slerped.interpolate_into(&from, &onto, k);
            let off = out.rotations[0].angle_between(slerped.rotations[0]);
            assert!(off < 1e-3, "k {k}: {off} rad from the slerp");
        }
    }
}
