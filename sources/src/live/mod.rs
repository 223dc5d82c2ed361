//! The shared API of live pose sources (VMC/OSC, serial IMU suits, webcams).
//!
//! ```text
//!   device ──bytes──▶ RawTap (optional: raw input into a recording)
//!      │
//!      └──▶ decoder ──▶ LiveSource::next_frame(timeout, &mut Pose) ──▶ server engine
//!                            │
//!                            └─ LiveSource::status(): Connecting → Live ⇄ Lost
//! ```
//!
//! A live source is driven by the server from its own thread: it blocks in
//! [`LiveSource::next_frame`] for at most the given timeout, fills a caller-owned [`Pose`] and
//! returns a [`FrameMeta`]. It never panics on bad input: bad packets are counted in
//! [`SourceStatus::dropped`] and skipped. Silence beyond a source's timeout turns its state to
//! [`SourceState::Lost`]; the next good input brings it back to [`SourceState::Live`].

mod health;
pub mod humanoid;

use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_retarget::{Pose, Skeleton};

pub use crate::error::SourceError;
pub use crate::recording::{RawKind, RawPacket};
pub use health::HealthTracker;
/// Per-stage latency rings (plain data the server's engine keeps too).
pub use rigcast_protocol::stage_times::{self, StageTimes};

/// Connection state of a live source (live sources never report `Finished`).
pub use rigcast_protocol::control::SourceState;

/// Health of a live source (plain data, shared with the engine through the protocol crate).
pub use rigcast_protocol::status::SourceStatus;

/// Provenance of one frame written by [`LiveSource::next_frame`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameMeta {
    /// Per-source sequence number, increasing by one per produced frame.
    pub seq: u64,
    /// When the input was captured (or received), nanoseconds since the Unix epoch.
    pub capture_nanos: u64,
    /// True when [`LiveSource::skeleton`] changed since the previous frame (the first frame
    /// always sets it); the caller should re-read the skeleton and rebuild its mapping.
    pub skeleton_changed: bool,
}

/// What [`LiveSource::next_frame`] returns: the new frame's metadata, `None` when nothing new
/// arrived in time, or the error that ended the input.
pub type NextFrame = Result<Option<FrameMeta>, SourceError>;

/// A live pose source.
///
/// Driven from its own thread by the server; never panics on bad input.
pub trait LiveSource: Send {
    /// Name for status reports (e.g. `vmc:39539`).
    fn name(&self) -> &str;
    /// None until known (a VMC sender's skeleton is learnt from its packets).
    fn skeleton(&self) -> Option<Arc<Skeleton>>;
    /// Blocks at most `timeout`; Ok(None) when nothing new arrived. Fills `out` (sized to
    /// skeleton(); a wrongly sized `out` is resized, which allocates only then).
    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame;
    /// Current health.
    fn status(&self) -> SourceStatus;
    /// Installs a hook that receives every raw input unit (OSC datagram, serial read chunk,
    /// landmark record) before decoding, so it can be recorded. Sources without raw input
    /// ignore it.
    fn set_raw_tap(&mut self, tap: Option<Box<dyn RawTap>>) {
        let _ = tap;
    }
}

/// Receives every raw input of a live source (e.g. to write it into a recording). Called on the
/// source's thread, so it must be quick; it must not block on IO for long.
pub trait RawTap: Send {
    /// One raw input unit, received at `capture_nanos` (Unix epoch nanoseconds).
    fn raw(&mut self, kind: RawKind, capture_nanos: u64, bytes: &[u8]);
}

/// Stamps a raw input unit as it arrives — a monotonic instant for health, Unix nanoseconds
/// for the recording — and hands it to the tap, if one is set.
pub fn stamp_raw(
    tap: &mut Option<Box<dyn RawTap>>,
    kind: RawKind,
    bytes: &[u8],
) -> (std::time::Instant, u64) {
    let received = std::time::Instant::now();
    let capture_nanos = unix_nanos_now();
    if let Some(tap) = tap.as_mut() {
        tap.raw(kind, capture_nanos, bytes);
    }
    (received, capture_nanos)
}

/// A tap that writes every raw input into a recording as raw-packet records, tagged with
/// `source_id`. Several sources can share one writer. Write errors are counted, not raised
/// (the source thread must keep running); check [`RecordingTap::errors`].
pub struct RecordingTap<W: std::io::Write + Send> {
    /// The shared writer.
    pub writer: Arc<std::sync::Mutex<crate::recording::RecordingWriter<W>>>,
    /// Source id written with each packet.
    pub source_id: u32,
    errors: Arc<std::sync::atomic::AtomicU64>,
}

impl<W: std::io::Write + Send> RecordingTap<W> {
    /// A tap writing into `writer` as `source_id`.
    pub fn new(
        writer: Arc<std::sync::Mutex<crate::recording::RecordingWriter<W>>>,
        source_id: u32,
    ) -> Self {
        RecordingTap {
            writer,
            source_id,
            errors: Arc::default(),
        }
    }

    /// Shared count of failed writes.
    pub fn errors(&self) -> Arc<std::sync::atomic::AtomicU64> {
        self.errors.clone()
    }
}

impl<W: std::io::Write + Send> RawTap for RecordingTap<W> {
    fn raw(&mut self, kind: RawKind, capture_nanos: u64, bytes: &[u8]) {
        let ok = match self.writer.lock() {
            Ok(mut w) => w
                .write_raw(self.source_id, kind, capture_nanos, bytes)
                .is_ok(),
            Err(_) => false,
        };
        if !ok {
            self.errors
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// A tap that keeps everything in memory (tests, short captures).
#[derive(Debug, Default, Clone)]
pub struct MemoryTap {
    /// Shared list of captured packets.
    pub packets: Arc<std::sync::Mutex<Vec<RawPacket>>>,
}

impl RawTap for MemoryTap {
    fn raw(&mut self, kind: RawKind, capture_nanos: u64, bytes: &[u8]) {
        if let Ok(mut list) = self.packets.lock() {
            list.push(RawPacket {
                source_id: 0,
                kind,
                capture_nanos,
                bytes: bytes.to_vec(),
            });
        }
    }
}

/// Current wall-clock time, nanoseconds since the Unix epoch (0 if the clock is before 1970).
pub fn unix_nanos_now() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// Sleeps until `due`, but never past `deadline`: true when `due` was reached (the frame may
/// be released), false when the caller's wait ran out first (return "nothing new"). Paces
/// recorded input to its timestamps.
pub(crate) fn wait_until(due: Instant, deadline: Instant) -> bool {
    let reached = due <= deadline;
    std::thread::sleep(due.min(deadline).saturating_duration_since(Instant::now()));
    reached
}

/// Plays timestamped input (a file, a recording) at its own pace: the wall clock of input time
/// 0 is set by the first frame asked about, and each later time is due that much later.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Pace {
    start: Option<Instant>,
}

impl Pace {
    /// When input time `time_secs` is due; the first call makes it due at `now`. Times are
    /// clamped to 0..=1 year (a corrupt or NaN stamp must not panic the source's thread).
    pub(crate) fn due(&mut self, time_secs: f64, now: Instant) -> Instant {
        const YEAR_SECS: f64 = 365.0 * 86_400.0;
        let secs = if time_secs.is_finite() {
            time_secs.clamp(0.0, YEAR_SECS)
        } else {
            0.0
        };
        let t = Duration::from_secs_f64(secs);
        let start = *self
            .start
            .get_or_insert_with(|| now.checked_sub(t).unwrap_or(now));
        start.checked_add(t).unwrap_or(now)
    }
}

/// Resizes `out` to `skeleton` if needed (allocates only when the size changes).
pub(crate) fn fit_pose(out: &mut Pose, skeleton: &Skeleton) {
    if out.num_bones() != skeleton.num_bones() || out.translations.len() != skeleton.num_bones() {
        *out = skeleton.rest_pose();
    }
}

#[cfg(test)]
mod pace_tests {
    use super::*;

    #[test]
    fn corrupt_times_do_not_panic_and_good_ones_keep_their_spacing() {
        let now = Instant::now();
        let mut p = Pace::default();
        let first = p.due(2.0, now);
        assert_eq!(first, now);
        assert_eq!(p.due(2.5, now), now + Duration::from_millis(500));
        for bad in [f64::NAN, f64::INFINITY, -1.0, 1e300] {
            // Only that they return (no panic, no overflow) matters here, not the instants.
            let _ = Pace::default().due(bad, now);
            let _ = p.due(bad, now);
        }
    }
}
