//! Live sources (VMC, serial IMU suits, video): one std thread each, blocking in
//! `LiveSource::next_frame` and handing its poses to the engine through its door.
//!
//! ```text
//!  thread: next_frame(50 ms, &mut pose) ─▶ skeleton changed? ─▶ subject shape, `subjects_changed`
//!            │                                                  + `skeleton` to clients, re-map
//!            └─▶ SourceDoor::hand_over (copy, no allocation) ─▶ the engine's Input::Frame
//!          every ~100 ms: status() ─▶ the live report (fps, latency, frames, dropped) on the
//!                                     subject; its state ─▶ the engine's Input::Health
//! ```
//!
//! A subject the cluster relays from another node is no source of this node's engine: its
//! thread writes the subject's slot and health itself ([`LiveFeed::Relayed`]).
//!
//! Skeleton changes are rate-limited: a sender that changes its skeleton faster than once
//! per [`MIN_SKELETON_CHANGE_INTERVAL`] (each change re-maps, re-announces and may add a cache
//! entry) has its frames on the newer skeleton held back, and counted, until the interval has
//! passed; then the latest skeleton is applied.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_retarget::Pose;
use rigcast_sources::live::LiveSource;
use tokio::sync::broadcast;

use crate::recorder::Recorder;
use rigcast_engine::clock::TickTime;
use rigcast_engine::events::Event;
use rigcast_engine::inbox::{Inbox, SourceDoor};
use rigcast_engine::slot::FrameWriter;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::EngineCommand;

/// How long one `next_frame` call may block (bounds shutdown latency).
const POLL: Duration = Duration::from_millis(50);
/// How often the health report is refreshed.
const STATUS_EVERY: Duration = Duration::from_millis(100);
/// Shortest time between two applied skeleton changes of one source.
pub const MIN_SKELETON_CHANGE_INTERVAL: Duration = Duration::from_secs(1);

/// Where a live source's poses and health go.
pub enum LiveFeed {
    /// To the engine (a source of this node): its door (which wakes the engine's loop for
    /// each pose when the tick should take it at once: cameras).
    Engine(SourceDoor),
    /// A subject relayed from another node (no source of this node's engine): its slot,
    /// written here, and its health, set here.
    Relayed(FrameWriter),
}

/// What a live-source thread talks to.
pub struct LiveContext {
    /// The subject it feeds.
    pub subject: Arc<Subject>,
    /// Where its poses and health go.
    pub feed: LiveFeed,
    /// All subjects (for `subjects_changed`).
    pub subjects: Arc<rigcast_engine::subject_list::SubjectList>,
    /// Control messages to clients.
    pub events: broadcast::Sender<Event>,
    /// The engine's inbox (a skeleton change asks for a re-map through it).
    pub inbox: Inbox,
    /// Recording of skeleton changes, if any.
    pub recorder: Option<Arc<Recorder>>,
    /// Set on shutdown.
    pub stop: Arc<AtomicBool>,
}

impl LiveContext {
    /// The source's state now: to the engine, or set here for a relayed subject (clients
    /// hear of a change at once either way).
    fn health(&self, state: rigcast_protocol::SourceState) {
        match &self.feed {
            LiveFeed::Engine(door) => door.health(state),
            LiveFeed::Relayed(_) => {
                let changed = self.subject.health.state() != state;
                self.subject.health.set_state(state);
                if changed {
                    // Err only means no client is connected.
                    let _ = self.events.send(Event::source_status(
                        &self.subjects.snapshot(),
                        Instant::now(),
                    ));
                }
            }
        }
    }

    /// Hands over a new pose (`false`: refused by the checks).
    fn hand_over(&self, pose: &mut Pose, seq: u64, capture_nanos: u64) -> bool {
        let time = TickTime::now();
        match &self.feed {
            LiveFeed::Engine(door) => door.hand_over(time, seq, capture_nanos, pose),
            LiveFeed::Relayed(tx) => {
                let s = &self.subject;
                if !s.admit(pose, time.instant) {
                    return false;
                }
                s.publish_source_pose(tx, pose, time, (capture_nanos, seq));
                true
            }
        }
    }
}

/// Runs a live source until `stop` is set.
pub fn run_live(mut source: Box<dyn LiveSource>, ctx: LiveContext) {
    let mut pose: Pose = ctx.subject.skeleton().rest_pose();
    let mut last_status = Instant::now() - STATUS_EVERY;
    let mut last_error: Option<String> = None;
    let mut skeleton_pending = false;
    let mut last_skeleton_change: Option<Instant> = None;
    while !ctx.stop.load(Ordering::Relaxed) {
        // First, so that frames held back below never delay the health report.
        if last_status.elapsed() >= STATUS_EVERY {
            last_status = Instant::now();
            let status = source.status();
            let state = status.state;
            if let Ok(mut g) = ctx.subject.health.live.lock() {
                *g = Some(status);
            }
            // Clients hear of a loss or a recovery now, not at the next periodic report.
            ctx.health(state);
        }
        match source.next_frame(POLL, &mut pose) {
            Ok(Some(meta)) => {
                skeleton_pending |= meta.skeleton_changed;
                if skeleton_pending {
                    if last_skeleton_change
                        .is_some_and(|t| t.elapsed() < MIN_SKELETON_CHANGE_INTERVAL)
                    {
                        // This frame is on a skeleton clients have not been told about.
                        ctx.subject
                            .stats
                            .skeleton_frames_limited
                            .fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    skeleton_pending = false;
                    if let Some(skeleton) = source.skeleton() {
                        if ctx.subject.set_skeleton(skeleton.clone()) {
                            last_skeleton_change = Some(Instant::now());
                            ctx.subject
                                .stats
                                .skeleton_changes
                                .fetch_add(1, Ordering::Relaxed);
                            announce_skeleton(&ctx);
                        }
                    }
                }
                // Checked as a whole where it enters the engine (the door or, relayed,
                // here): each value may be finite while their sums (root + hips, a chain in
                // FK) are not.
                if ctx.hand_over(&mut pose, meta.seq, meta.capture_nanos) {
                    last_error = None;
                }
            }
            Ok(None) => {}
            Err(e) => {
                let text = e.to_string();
                if last_error.as_deref() != Some(text.as_str()) {
                    tracing::warn!("source {}: {text}", ctx.subject.info().name);
                    last_error = Some(text);
                }
                // Device errors repeat quickly; don't spin.
                std::thread::sleep(POLL);
            }
        }
    }
}

/// Tells clients, the recorder and the mapper about a new skeleton.
fn announce_skeleton(ctx: &LiveContext) {
    let shape = ctx.subject.shape();
    // Err only means no client is listening right now.
    let _ = ctx
        .events
        .send(Event::subjects_changed(&ctx.subjects.snapshot()));
    // Err only means no client is listening right now.
    let _ = ctx.events.send(Event::Skeleton(shape.clone()));
    if let Some(r) = &ctx.recorder {
        r.skeleton(ctx.subject.id, &shape.info.name, &shape.skeleton);
    }
    ctx.inbox.notice(EngineCommand::SkeletonChanged {
        subject: ctx.subject.id,
    });
}
