//! The tick side of a performer: source subject(s) → [`Mapping::apply`] → target subject, with
//! easing when a source is lost and when it comes back.
//!
//! ```text
//!  sources' latest poses ─copy─▶ inputs (preallocated) ─apply─▶ foot lock ─▶ live ─┐
//!                                                                     ├─ blend ─▶ display ─▶ target watch
//!  source lost:  from = display at loss ──slerp (0.5 s)──▶ the character's own rest, where it
//!                stands (or hold `from`)
//!  source back:  from = display at return ──slerp (0.2 s)──▶ live
//! ```
//!
//! Mappings are built off the tick (see `mapper`) and handed over through a mailbox the tick
//! polls with `try_lock`, so a rebuild never stalls a tick. Every buffer is sized when a
//! mapping arrives; steady-state ticks allocate nothing.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rigcast_retarget::footplant::FootLock;
use rigcast_retarget::{Frame, Mapping, Pose};
use tokio::sync::watch;

use crate::config::OnLost;
use crate::engine::unix_nanos;
use crate::subject::Subject;
use rigcast_protocol::SourceState;

/// Time to ease to rest after a loss.
pub const EASE_OUT: Duration = Duration::from_millis(500);
/// Time to ease back in after a return.
pub const EASE_IN: Duration = Duration::from_millis(200);
/// Most source subjects one target can blend (keeps the per-tick input list on the stack).
pub const MAX_INPUTS: usize = 8;

/// A mapping ready for the tick.
#[derive(Debug)]
pub struct BuiltMapping {
    /// The job.
    pub mapping: Mapping,
    /// Pins the target's feet while the source's are planted (`None`: off, or nothing to
    /// lock on this character).
    pub foot_lock: Option<FootLock>,
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
    tx: watch::Sender<Frame>,
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
    last_input_seqs: [u64; MAX_INPUTS],
    /// Capture time of the foot lock's source input at its last sample.
    last_lock_capture: u64,
    seq: u64,
    published: bool,
    /// The eased-to pose has been published (nothing changes until the source returns).
    settled: bool,
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

/// Smooth 0→1 ramp with zero slope at both ends (no jump when easing starts or ends).
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl Performer {
    /// A performer writing into `tx` (the target subject's slot).
    pub fn new(
        target: Arc<Subject>,
        tx: watch::Sender<Frame>,
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
            from: rest.clone(),
            display: rest.clone(),
            settle: rest.clone(),
            rest,
            phase: Phase::Live,
            on_lost,
            last_input_seqs: [0; MAX_INPUTS],
            last_lock_capture: 0,
            seq: 0,
            published: false,
            settled: false,
        }
    }

    fn take_new_mapping(&mut self) {
        let Ok(mut slot) = self.mailbox.try_lock() else {
            return;
        };
        let Some(built) = slot.take() else { return };
        drop(slot);
        // Rare (a rebuild): size the input copies for the new source skeletons.
        self.inputs = (0..built.mapping.num_inputs())
            .filter_map(|i| built.mapping.source(i).map(|s| s.rest_pose()))
            .collect();
        self.current = Some(built);
    }

    /// Runs one tick: apply, ease, publish. Allocates nothing in steady state.
    pub fn tick(&mut self, now: Instant) {
        self.take_new_mapping();
        let Some(built) = self.current.as_mut() else {
            return;
        };
        let n = self.inputs.len().min(MAX_INPUTS);
        if n == 0 || n != self.sources.len() {
            return;
        }
        // Copy the sources' latest poses; skip the tick until every source has produced a
        // pose that fits the mapping (after a skeleton change the rebuild is on its way).
        let mut newest_capture = 0u64;
        let mut changed = false;
        let mut captures = [0u64; MAX_INPUTS];
        let mut lost = false;
        for (i, (src, copy)) in self.sources.iter().zip(&mut self.inputs).enumerate() {
            let frame = src.latest.borrow();
            if frame.capture_nanos == 0 || frame.pose.num_bones() != copy.num_bones() {
                return;
            }
            copy.copy_from(&frame.pose);
            captures[i] = frame.capture_nanos;
            newest_capture = newest_capture.max(frame.capture_nanos);
            if frame.seq != self.last_input_seqs[i] {
                self.last_input_seqs[i] = frame.seq;
                changed = true;
            }
            lost |= src.health.state() == SourceState::Lost;
        }
        match (self.phase, lost) {
            (Phase::Live | Phase::Resuming(_), true) => {
                self.from.copy_from(&self.display);
                rest_in_place(&self.rest, &self.from, &mut self.settle);
                self.phase = Phase::Lost(now);
                self.settled = false;
            }
            (Phase::Lost(_), false) => {
                self.from.copy_from(&self.display);
                self.phase = Phase::Resuming(now);
                // The motion seen before the loss says nothing about the feet now.
                if let Some(lock) = built.foot_lock.as_mut() {
                    lock.reset();
                }
            }
            _ => {}
        }
        let mut moving = changed;
        match self.phase {
            Phase::Lost(t0) => match self.on_lost {
                OnLost::Ease => {
                    let k =
                        smoothstep(now.duration_since(t0).as_secs_f32() / EASE_OUT.as_secs_f32());
                    self.display.interpolate_into(&self.from, &self.settle, k);
                    // Publish up to and including the frame that reaches rest.
                    moving = !self.settled;
                    self.settled = k >= 1.0;
                }
                OnLost::Hold => {
                    self.display.copy_from(&self.from);
                    moving = !self.settled;
                    self.settled = true;
                }
            },
            Phase::Live | Phase::Resuming(_) => {
                let mut refs: [&Pose; MAX_INPUTS] = [&self.inputs[0]; MAX_INPUTS];
                for (r, p) in refs.iter_mut().zip(&self.inputs) {
                    *r = p;
                }
                if built.mapping.apply(&refs[..n], &mut self.live).is_err() {
                    return;
                }
                if let Some(lock) = built.foot_lock.as_mut() {
                    let input = built.mapping.root_input().unwrap_or(0).min(n - 1);
                    let capture = captures[input];
                    let fresh = capture != self.last_lock_capture;
                    let dt = capture.saturating_sub(self.last_lock_capture) as f32 * 1e-9;
                    self.last_lock_capture = capture;
                    lock.apply_live(
                        &self.inputs[input],
                        fresh,
                        dt.min(MAX_SAMPLE_GAP_SECS),
                        &mut self.live,
                    );
                    let held = (0..lock.target_legs().count().min(32))
                        .filter(|&i| lock.is_locked(i))
                        .fold(0u32, |bits, i| bits | 1 << i);
                    self.target
                        .stats
                        .feet_locked
                        .store(held, std::sync::atomic::Ordering::Relaxed);
                }
                if let Phase::Resuming(t0) = self.phase {
                    let k =
                        smoothstep(now.duration_since(t0).as_secs_f32() / EASE_IN.as_secs_f32());
                    self.display.interpolate_into(&self.from, &self.live, k);
                    moving = true;
                    if k >= 1.0 {
                        self.phase = Phase::Live;
                    }
                } else {
                    self.display.copy_from(&self.live);
                }
            }
        }
        // A new seq whenever the pose changes (clients skip repeated seqs).
        if !moving && self.published {
            return;
        }
        self.seq += 1;
        self.published = true;
        let seq = self.seq;
        let capture = if matches!(self.phase, Phase::Lost(_)) {
            unix_nanos()
        } else {
            newest_capture
        };
        let display = &self.display;
        self.tx.send_modify(|f| {
            if f.pose.num_bones() == display.num_bones() {
                f.pose.copy_from(display);
            }
            f.seq = seq;
            f.capture_nanos = capture;
        });
        self.target.stats.input.tick();
        self.target
            .stats
            .last_capture_nanos
            .store(capture, std::sync::atomic::Ordering::Relaxed);
    }
}
