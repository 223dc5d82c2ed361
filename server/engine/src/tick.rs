//! The engine's tick: performers run, then each subject's latest pose is encoded once and
//! handed out.
//!
//! ```text
//!  source slots (watch<Frame>, latest frame wins) ─┐
//!                                                  ▼
//!   Ticker::tick(TickTime, &mut impl TickOutput)   (the time is an input: no clock read here)
//!     ├─ performers: sources' poses → mapping → foot lock / fallback → target slots
//!     ├─ encode every subject's frame into scratch → one shared Bytes per subject
//!     ├─ VMC: encode bundles (reused buffers) ─▶ TickOutput::datagram(receiver, bytes)
//!     └─ TickOutput::frame(OutFrame) per subject, all at the end of the tick
//! ```
//!
//! The tick does no IO: what it produces goes to a [`TickOutput`]. The host's tick task
//! (`tick_task` in the server) drives it at a fixed rate and broadcasts the frames to the client sessions
//! and sends the datagrams on its UDP socket; a test drives it on a simulated clock and keeps
//! what came out. Per tick the only allocation is the shared `Bytes` per subject (it must
//! outlive the tick because clients send it later); everything else reuses buffers.

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

use bytes::Bytes;
use rigcast_protocol::frame::{append_frame_v2, encode_frame, FrameHeader};
use rigcast_protocol::vmc::{VmcBone, VmcEncoder};
use rigcast_retarget::{forward_kinematics, Frame, WorldTransform};

use crate::clock::TickTime;
use crate::performer::{BuiltMapping, Performer};
use crate::subject::{Subject, SubjectShape};

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
    /// The frame's capture time and when it was encoded, Unix ns, as in its header (0 for
    /// frames this node did not encode): for the latency figures of its first write.
    pub capture_nanos: u64,
    /// See `capture_nanos`.
    pub send_nanos: u64,
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

/// A VMC receiver and the subject it receives.
#[derive(Debug, Clone)]
pub struct VmcTarget {
    /// Receiver address.
    pub addr: SocketAddr,
    /// Index of the subject streamed to it.
    pub subject_index: usize,
}

/// Where a tick's outputs go. The engine hands them over and does no IO itself.
pub trait TickOutput {
    /// One subject's frame of this tick; every subject's is handed over at the end of the
    /// tick, so a client woken by the first finds the rest queued and writes them in one go.
    fn frame(&mut self, frame: OutFrame);
    /// One VMC bundle (≤ 1500 bytes) for the receiver at `to`. Must not block.
    fn datagram(&mut self, to: SocketAddr, bundle: &[u8]);
}

/// Everything the tick needs.
pub struct TickContext {
    /// Subjects in id order.
    pub subjects: Arc<Vec<Arc<Subject>>>,
    /// VMC receivers (empty when there are none).
    pub vmc: Vec<VmcTarget>,
    /// Retargeted characters, run before encoding so their subjects stream this tick's pose.
    pub performers: Vec<Performer>,
}

/// The body of one tick, with its reused buffers: a state machine fed the tick's time that
/// hands its frames and datagrams to a [`TickOutput`].
pub struct Ticker {
    ctx: TickContext,
    scratch: Vec<u8>,
    vmc_encoder: VmcEncoder,
    worlds: Vec<WorldTransform>,
    /// This tick's frames, handed over together once every subject is encoded.
    outgoing: Vec<OutFrame>,
    /// The first tick's time: VMC bundles carry the time since.
    start: Option<Instant>,
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
            start: None,
        }
    }

    /// Subject `id` of the tick's list.
    pub fn subject(&self, id: u32) -> Option<&Arc<Subject>> {
        self.ctx.subjects.get(id as usize).filter(|s| s.id == id)
    }

    /// Hands `built` to the performer of target `id` (taken at its next tick); `false` when
    /// no performer drives that target.
    pub fn offer_mapping(&self, id: u32, built: BuiltMapping) -> bool {
        match self.ctx.performers.iter().find(|p| p.target.id == id) {
            Some(p) => {
                p.offer(built);
                true
            }
            None => false,
        }
    }

    /// One whole tick at `time`: [`Ticker::perform`], then [`Ticker::publish`] stamped with
    /// the same time.
    pub fn tick(&mut self, time: TickTime, out: &mut impl TickOutput) {
        self.perform(time);
        self.publish(time, time.unix_nanos, out);
    }

    /// Runs the performers at `time` (their targets' slots get this tick's poses).
    pub fn perform(&mut self, time: TickTime) {
        for p in &mut self.ctx.performers {
            p.tick(time);
        }
    }

    /// Encodes the latest frame of every subject, stamped `send_nanos` (when it is encoded,
    /// as the protocol defines it), and hands the frames and VMC bundles to `out`. Allocates
    /// exactly one shared buffer per subject that has produced a frame; nothing else once
    /// warmed up.
    pub fn publish(&mut self, time: TickTime, send_nanos: u64, out: &mut impl TickOutput) {
        let vmc_secs = time
            .instant
            .saturating_duration_since(*self.start.get_or_insert(time.instant))
            .as_secs_f32();
        let subjects = self.ctx.subjects.clone();
        for (index, subject) in subjects.iter().enumerate() {
            let frame = subject.latest.borrow();
            if frame.capture_nanos == 0 {
                continue; // the source has not produced anything yet
            }
            let shape = subject.shape();
            // Another node's subject: its frames reach clients as they arrive from the cluster
            // (cluster::run_relay), so the tick only serves its VMC receivers.
            let relayed = subject.is_relayed();
            let v2_at = self.encode(subject.id, &frame, &shape, send_nanos, relayed);
            if self.ctx.vmc.iter().any(|t| t.subject_index == index) {
                self.send_vmc(index, &frame, &shape, vmc_secs, out);
            }
            let capture = frame.capture_nanos;
            drop(frame);
            if relayed {
                continue;
            }
            // Timed only when a live source's pose is behind the frame (not a replay's, not a
            // fallback the tick made): `capture_nanos` 0 tells the clients' writes so too.
            let published = subject.stats.published_nanos.load(Ordering::Relaxed);
            let timed_capture = if published == 0 { 0 } else { capture };
            if let Ok(mut wire) = subject.stats.wire.lock() {
                wire.ticked(timed_capture, published, time.unix_nanos, send_nanos);
            }
            // The one allocation per subject per tick: the shared, immutable frame, which must
            // outlive the tick because client tasks send it later.
            let bytes = Bytes::copy_from_slice(&self.scratch);
            self.outgoing.push(OutFrame {
                subject: subject.id,
                bytes,
                v2_at,
                capture_nanos: timed_capture,
                send_nanos,
            });
        }
        for frame in self.outgoing.drain(..) {
            out.frame(frame);
        }
    }

    /// Encodes `frame` into `scratch` in both versions (nothing for a relayed subject);
    /// returns where the version 2 frame starts.
    fn encode(
        &mut self,
        subject: u32,
        frame: &Frame,
        shape: &SubjectShape,
        send_nanos: u64,
        relayed: bool,
    ) -> usize {
        let header = FrameHeader {
            flags: 0,
            subject,
            seq: frame.seq,
            capture_nanos: frame.capture_nanos,
            send_nanos,
            missed_frames: 0,
        };
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
        if !relayed && frame.pose.num_bones() == shape.skeleton.num_bones() {
            append_frame_v2(
                &mut self.scratch,
                &header,
                &frame.pose.rotations,
                &frame.pose.translations,
                &shape.translated,
            );
        }
        // Otherwise a live source's skeleton just changed and its pose is not resized yet:
        // no v2 frame this tick rather than one that contradicts its skeleton message.
        v2_at
    }

    /// Encodes subject `index`'s pose as VMC bundles for its receivers.
    fn send_vmc(
        &mut self,
        index: usize,
        frame: &Frame,
        shape: &SubjectShape,
        secs: f32,
        out: &mut impl TickOutput,
    ) {
        let plan = &shape.vmc;
        let pose = &frame.pose;
        if pose.num_bones() != shape.skeleton.num_bones() {
            return;
        }
        if !plan.direct {
            // Growing once to the largest skeleton; then reused.
            if self.worlds.len() < pose.num_bones() {
                self.worlds
                    .resize(pose.num_bones(), WorldTransform::IDENTITY);
            }
            forward_kinematics(&shape.skeleton, pose, &mut self.worlds[..pose.num_bones()]);
        }
        let worlds = &self.worlds;
        let direct = plan.direct;
        let bones = plan.bones.iter().map(|(name, b, anc)| {
            let (translation, rotation) = if direct {
                (pose.translations[*b], pose.rotations[*b])
            } else {
                // Relative to the nearest sent ancestor, in the receivers' normalised T-pose
                // frame.
                crate::vmc_pose::normalised_local(worlds, &plan.norm, *b, *anc)
            };
            VmcBone {
                name,
                translation,
                rotation,
            }
        });
        for bundle in self.vmc_encoder.encode(secs, bones) {
            for t in self.ctx.vmc.iter().filter(|t| t.subject_index == index) {
                out.datagram(t.addr, bundle);
            }
        }
    }
}
