//! Live sources (VMC, serial IMU suits, video): one std thread each, blocking in
//! `LiveSource::next_frame` and publishing into the subject's frame slot.
//!
//! ```text
//!  thread: next_frame(50 ms, &mut pose) ─▶ skeleton changed? ─▶ subject shape, `subjects_changed`
//!            │                                                  + `skeleton` to clients, re-map
//!            └─▶ FrameWriter::send_modify (copy, no allocation)
//!          every ~100 ms: status() ─▶ subject health (state, fps, latency, frames, dropped)
//! ```
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
use tokio::sync::{broadcast, mpsc};

use crate::recorder::Recorder;
use rigcast_engine::clock::unix_nanos;
use rigcast_engine::events::Event;
use rigcast_engine::slot::FrameWriter;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::EngineCommand;

/// How long one `next_frame` call may block (bounds shutdown latency).
const POLL: Duration = Duration::from_millis(50);
/// How often the health report is refreshed.
const STATUS_EVERY: Duration = Duration::from_millis(100);
/// Shortest time between two applied skeleton changes of one source.
pub const MIN_SKELETON_CHANGE_INTERVAL: Duration = Duration::from_secs(1);

/// What a live-source thread talks to.
pub struct LiveContext {
    /// The subject it feeds.
    pub subject: Arc<Subject>,
    /// Its slot.
    pub tx: FrameWriter,
    /// All subjects (for `subjects_changed`).
    pub subjects: Arc<rigcast_engine::subject_list::SubjectList>,
    /// Control messages to clients.
    pub events: broadcast::Sender<Event>,
    /// Requests to the mapper.
    pub commands: mpsc::Sender<EngineCommand>,
    /// Recording of skeleton changes, if any.
    pub recorder: Option<Arc<Recorder>>,
    /// Set on shutdown.
    pub stop: Arc<AtomicBool>,
    /// Notified after each new pose when the tick should take it at once (cameras: see
    /// [`crate::tick_task::run_engine`]); `None` for sources the tick samples at its own rate.
    pub wake: Option<Arc<tokio::sync::Notify>>,
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
            let changed = ctx.subject.health.state() != status.state;
            ctx.subject.health.set_state(status.state);
            if let Ok(mut g) = ctx.subject.health.live.lock() {
                *g = Some(status);
            }
            if changed {
                // Clients hear of a loss or a recovery now, not at the next periodic report.
                // Err only means no client is connected.
                let _ = ctx.events.send(Event::source_status(
                    &ctx.subjects.snapshot(),
                    Instant::now(),
                ));
            }
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
                // Checked as a whole where it enters the engine: each value may be finite
                // while their sums (root + hips, a chain in FK) are not.
                if let Err(refusal) = pose.check_values() {
                    let shape = ctx.subject.shape();
                    let names = shape.skeleton.names();
                    let name = names.get(refusal.bone).map_or("?", |n| n.as_str());
                    ctx.subject.stats.reject_pose(refusal, name, Instant::now());
                    continue;
                }
                let capture = if meta.capture_nanos == 0 {
                    unix_nanos()
                } else {
                    meta.capture_nanos
                };
                // Before the frame: a tick that sees the new frame sees when it was handed over.
                ctx.subject
                    .stats
                    .published_nanos
                    .store(unix_nanos(), Ordering::Relaxed);
                ctx.tx.send_modify(|f| {
                    if f.pose.num_bones() == pose.num_bones() {
                        f.pose.copy_from(&pose);
                    } else {
                        // Only after a skeleton change.
                        f.pose = pose.clone();
                    }
                    f.seq = meta.seq.max(f.seq + 1);
                    f.capture_nanos = capture;
                });
                if let Some(wake) = &ctx.wake {
                    wake.notify_one();
                }
                ctx.subject.stats.input.tick(Instant::now());
                ctx.subject
                    .stats
                    .last_capture_nanos
                    .store(capture, Ordering::Relaxed);
                last_error = None;
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
    // Fails only when the mapper has stopped (shutdown).
    let _ = ctx.commands.blocking_send(EngineCommand::SkeletonChanged {
        subject: ctx.subject.id,
    });
}
