//! The engine: source tasks feeding `watch` slots, and the fixed-rate tick that encodes each
//! subject's latest pose once and fans it out.
//!
//! ```text
//!  source task ─send_modify─▶ watch<Frame> ─┐ (latest frame wins; the pose buffer is reused)
//!  source task ─send_modify─▶ watch<Frame> ─┤
//!                                           ▼
//!                 tick (interval, MissedTickBehavior::Skip, never awaits a client)
//!                   ├─ encode frame into scratch Vec → one shared Bytes per subject
//!                   ├─ broadcast::send(OutFrame) per subject, all at the end of the tick ──▶ client tasks (lag ⇒ told, stays)
//!                   └─ VMC: encode bundles (reused buffers) → try_send_to each receiver
//! ```
//!
//! Per tick the only allocation is the shared `Bytes` per subject (it must outlive the tick
//! because clients send it later); everything else reuses buffers.

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_protocol::frame::{append_frame_v2, encode_frame, FrameHeader};
use rigcast_protocol::vmc::{VmcBone, VmcEncoder};
use rigcast_retarget::{forward_kinematics, Frame, WorldTransform};
use tokio::sync::{broadcast, watch};
use tokio::time::MissedTickBehavior;
use tokio_tungstenite::tungstenite::Bytes;

use crate::clock::unix_nanos;
use crate::performer::Performer;
use crate::stats::Stats;
use rigcast_protocol::SourceState;
use rigcast_sources::Replay;

/// One subject's pose of one tick on its way to clients, encoded once per protocol version.
#[derive(Debug, Clone)]
pub struct OutFrame {
    /// Subject id.
    pub subject: u32,
    /// The version 1 frame followed by the version 2 frame, shared by every client (one
    /// allocation per subject per tick; a client takes its version's part, see
    /// [`OutFrame::version`]).
    pub bytes: Bytes,
    /// Where the version 2 frame starts in `bytes`.
    pub v2_at: usize,
}

impl OutFrame {
    /// The frame in protocol `version` (2, or 1 for anything else). Slicing shares the
    /// buffer; nothing is copied.
    pub fn version(&self, version: u16) -> Bytes {
        let at = self.v2_at.min(self.bytes.len());
        if version == rigcast_protocol::frame::FRAME_VERSION_2 {
            self.bytes.slice(at..)
        } else {
            self.bytes.slice(..at)
        }
    }
}

pub use crate::subject::Subject;

/// Requests to the mapper (from clients and live sources).
#[derive(Debug)]
pub enum EngineCommand {
    /// `set_mapping` from a client: merge into that target's table and rebuild.
    SetMapping {
        /// target subject
        subject: u32,
        /// target bone → source bone
        overrides: std::collections::BTreeMap<String, Option<String>>,
    },
    /// `set_performer` from a client: change how that target is run and rebuild.
    SetPerformer {
        /// target subject
        subject: u32,
        /// foot locking on or off (`None`: unchanged)
        foot_lock: Option<bool>,
    },
    /// A source subject's skeleton changed: rebuild the mappings that use it.
    SkeletonChanged {
        /// the source subject
        subject: u32,
    },
    /// Stop the mapper.
    Shutdown,
}

/// Runs one replay source until shutdown or (non-looping) end of clip.
///
/// Samples only on the clip's frame grid (frame k at k × frame_time / speed), so streamed
/// poses are exactly the file's frames; a late wake-up skips to the current frame.
pub async fn run_replay_source(
    player: Replay,
    speed: f64,
    tx: watch::Sender<Frame>,
    subject: Arc<Subject>,
    mut shutdown: watch::Receiver<bool>,
) {
    // A floor on the period keeps a very fast speed setting from spinning the runtime; a
    // ceiling keeps a huge frame time (or a tiny speed) from overflowing the timer.
    let period = (player.frame_time_secs() / speed).clamp(1e-3, 3600.0);
    let period = if period.is_nan() { 1e-3 } else { period };
    let mut interval = tokio::time::interval(Duration::from_secs_f64(period));
    interval.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let start = Instant::now();
    let mut last_k = None;
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = shutdown.changed() => break,
        }
        // Snap to the frame grid: frame k is due at k × period after start.
        let k = (start.elapsed().as_secs_f64() / period).floor() as u64;
        if last_k == Some(k) {
            continue;
        }
        last_k = Some(k);
        let now = unix_nanos();
        let mut finished = false;
        let elapsed_secs = k as f64 * period;
        tx.send_modify(|f| match player.sample(elapsed_secs, &mut f.pose) {
            Some(_) => {
                f.seq += 1;
                f.capture_nanos = now;
            }
            None => finished = true,
        });
        if finished {
            subject.health.set_state(SourceState::Finished);
            break;
        }
        subject.stats.input.tick();
        subject
            .stats
            .last_capture_nanos
            .store(now, Ordering::Relaxed);
    }
}

/// A VMC receiver and the subject it receives.
#[derive(Debug, Clone)]
pub struct VmcTarget {
    /// Receiver address.
    pub addr: SocketAddr,
    /// Index of the subject streamed to it.
    pub subject_index: usize,
}

/// Everything the tick needs.
pub struct TickContext {
    /// Subjects in id order.
    pub subjects: Arc<Vec<Arc<Subject>>>,
    /// Fan-out to clients.
    pub frames: broadcast::Sender<OutFrame>,
    /// Counters.
    pub stats: Arc<Stats>,
    /// Output rate.
    pub rate_hz: f64,
    /// VMC output socket and receivers (socket is `None` when there are none).
    pub vmc: Option<(std::net::UdpSocket, Vec<VmcTarget>)>,
    /// Retargeted characters, run before encoding so their subjects stream this tick's pose.
    pub performers: Vec<Performer>,
}

/// The fixed-rate tick. Never awaits anything but its interval and the shutdown signal.
pub async fn run_tick(ctx: TickContext, mut shutdown: watch::Receiver<bool>) {
    let mut interval = tokio::time::interval(Duration::from_secs_f64(1.0 / ctx.rate_hz));
    interval.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut ticker = Ticker::new(ctx);
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = shutdown.changed() => break,
        }
        ticker.tick();
    }
}

/// The body of one tick, with its reused buffers. Separate from [`run_tick`] so it can be run
/// synchronously (allocation test, benchmarks).
pub struct Ticker {
    ctx: TickContext,
    scratch: Vec<u8>,
    vmc_encoder: VmcEncoder,
    worlds: Vec<WorldTransform>,
    /// This tick's frames, handed to the clients together once every subject is encoded, so
    /// a client task woken by the first finds the rest queued and writes them in one go.
    outgoing: Vec<OutFrame>,
    start: Instant,
}

impl Ticker {
    /// A ticker over `ctx`.
    pub fn new(ctx: TickContext) -> Ticker {
        Ticker {
            ctx,
            scratch: Vec::new(),
            vmc_encoder: VmcEncoder::new(),
            worlds: Vec::new(),
            outgoing: Vec::new(),
            start: Instant::now(),
        }
    }

    /// Runs the performers, then encodes and publishes the latest frame of every subject (and
    /// VMC). Allocates exactly one shared buffer per subject that has produced a frame;
    /// nothing else once warmed up.
    pub fn tick(&mut self) {
        let tick_start = Instant::now();
        for p in &mut self.ctx.performers {
            p.tick(tick_start);
        }
        let ctx = &self.ctx;
        let send_nanos = unix_nanos();
        for (index, subject) in ctx.subjects.iter().enumerate() {
            let frame = subject.latest.borrow();
            if frame.capture_nanos == 0 {
                continue; // the source has not produced anything yet
            }
            let header = FrameHeader {
                flags: 0,
                subject: subject.id,
                seq: frame.seq,
                capture_nanos: frame.capture_nanos,
                send_nanos,
                missed_frames: 0,
            };
            // Another node's subject: its frames reach clients as they arrive from the cluster
            // (cluster::run_relay), so the tick only serves its VMC receivers.
            let relayed = subject.is_relayed();
            self.scratch.clear();
            if !relayed {
                encode_frame(
                    &mut self.scratch,
                    &header,
                    frame.pose.root_translation(),
                    &frame.pose.rotations,
                );
            }
            let v2_at = self.scratch.len();
            let shape = subject.shape();
            if !relayed && frame.pose.num_bones() == shape.skeleton.num_bones() {
                append_frame_v2(
                    &mut self.scratch,
                    &header,
                    &frame.pose.rotations,
                    &frame.pose.translations,
                    &shape.translated,
                );
            } else {
                // A live source's skeleton just changed and its pose is not resized yet:
                // no v2 frame this tick rather than one that contradicts its skeleton message.
                self.scratch.truncate(v2_at);
            }
            if let Some((socket, targets)) = &ctx.vmc {
                if targets.iter().any(|t| t.subject_index == index) {
                    let plan = &shape.vmc;
                    let pose = &frame.pose;
                    if pose.num_bones() == shape.skeleton.num_bones() {
                        if !plan.direct {
                            // Growing once to the largest skeleton; then reused.
                            if self.worlds.len() < pose.num_bones() {
                                self.worlds
                                    .resize(pose.num_bones(), WorldTransform::IDENTITY);
                            }
                            forward_kinematics(
                                &shape.skeleton,
                                pose,
                                &mut self.worlds[..pose.num_bones()],
                            );
                        }
                        let worlds = &self.worlds;
                        let direct = plan.direct;
                        let bones = plan.bones.iter().map(|(name, b, anc)| {
                            let (translation, rotation) = if direct {
                                (pose.translations[*b], pose.rotations[*b])
                            } else {
                                // Relative to the nearest sent ancestor, in the receivers'
                                // normalised T-pose frame.
                                crate::vmc_pose::normalised_local(worlds, &plan.norm, *b, *anc)
                            };
                            VmcBone {
                                name,
                                translation,
                                rotation,
                            }
                        });
                        let time = self.start.elapsed().as_secs_f32();
                        for bundle in self.vmc_encoder.encode(time, bones) {
                            for t in targets.iter().filter(|t| t.subject_index == index) {
                                // Non-blocking: a full socket buffer drops the datagram (counted)
                                // instead of stalling the tick.
                                if socket.send_to(bundle, t.addr).is_err() {
                                    ctx.stats.vmc_send_errors.fetch_add(1, Ordering::Relaxed);
                                }
                            }
                        }
                    }
                }
            }
            drop(frame);
            if relayed {
                continue;
            }
            // The one allocation per subject per tick: the shared, immutable frame, which must
            // outlive the tick because client tasks send it later.
            let bytes = Bytes::copy_from_slice(&self.scratch);
            self.outgoing.push(OutFrame {
                subject: subject.id,
                bytes,
                v2_at,
            });
        }
        for frame in self.outgoing.drain(..) {
            // Err only means "no client connected right now".
            let _ = ctx.frames.send(frame);
        }
        ctx.stats.record_tick(tick_start.elapsed());
    }
}
