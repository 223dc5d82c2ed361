//! A subject's counters: written by the tick and the threads that feed it with atomics (and a
//! few uncontended mutexes off the per-frame path), read by the host's status report.

use rigcast_protocol::control::StageLatency;
use rigcast_protocol::stage_times::StageTimes;
use rigcast_protocol::TargetMotion;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Measures an event rate over the time since the previous read. Reads no clock: whoever
/// counts an event or reads the rate passes the time.
#[derive(Debug, Default)]
pub struct RateMeter {
    count: AtomicU64,
    /// Whether the window has its start (the first event's time); checked without locking.
    started: std::sync::atomic::AtomicBool,
    /// Start of the window, the count then, and the last figure.
    window: Mutex<Option<(Instant, u64, f64)>>,
}

impl RateMeter {
    /// Counts one event, at `now`; the first one starts the window.
    #[inline]
    pub fn tick(&self, now: Instant) {
        if !self.started.load(Ordering::Relaxed) {
            self.start(now);
        }
        self.count.fetch_add(1, Ordering::Relaxed);
    }

    #[cold]
    fn start(&self, now: Instant) {
        if let Ok(mut w) = self.window.lock() {
            w.get_or_insert((now, self.total(), 0.0));
            self.started.store(true, Ordering::Relaxed);
        }
    }

    /// Total events.
    pub fn total(&self) -> u64 {
        self.count.load(Ordering::Relaxed)
    }

    /// Events per second from the previous read (or the first event) to `now` (windows
    /// shorter than 0.5 s reuse the previous figure so frequent polling does not produce
    /// noise; 0 before any event).
    pub fn rate_hz(&self, now: Instant) -> f64 {
        let Ok(mut guard) = self.window.lock() else {
            return 0.0;
        };
        let Some(w) = guard.as_mut() else {
            return 0.0;
        };
        let dt = now.saturating_duration_since(w.0).as_secs_f64();
        let count = self.total();
        if dt >= 0.5 {
            w.2 = count.saturating_sub(w.1) as f64 / dt;
            *w = (now, count, w.2);
        }
        w.2
    }
}

/// Per-subject input counters.
#[derive(Debug, Default)]
pub struct SubjectStats {
    /// Frames produced by the source.
    pub input: RateMeter,
    /// Capture time of the latest frame, Unix ns.
    pub last_capture_nanos: AtomicU64,
    /// Skeleton changes applied.
    pub skeleton_changes: AtomicU64,
    /// Frames held back by the skeleton-change rate limit.
    pub skeleton_frames_limited: AtomicU64,
    /// A target's feet held by its foot lock now: bit `i` for foot `i` of `locked_feet`
    /// (written by the tick, without allocating).
    pub feet_locked: std::sync::atomic::AtomicU32,
    /// The foot bones its foot lock holds, in bit order (empty: no foot lock). Written when a
    /// mapping is built.
    pub locked_feet: std::sync::Mutex<Vec<String>>,
    /// What drives a target now (written by the tick, read by `source_status`).
    pub motion: MotionCell,
    /// Poses refused where they entered the engine (see `rigcast_retarget::bounds`).
    pub rejected_poses: AtomicU64,
    /// Why the latest was refused (written off the tick, by the source's thread), and when.
    pub last_rejection: Mutex<Option<String>>,
    /// When the latest pose was refused (`None`: never).
    pub last_rejection_at: Mutex<Option<Instant>>,
    /// Why the subject's processing is stopped now (`None`: healthy). Written by the tick only
    /// when a fault starts or clears.
    pub fault: Mutex<Option<String>>,
    /// Faults caught in the subject's processing.
    pub faults_total: AtomicU64,
    /// When the pose behind the latest frame was handed to the engine, Unix ns (0: not
    /// measured): a live source's thread published it, or, for a target, its source's pose
    /// it was made from was.
    pub published_nanos: AtomicU64,
    /// Where its frames' time goes between the source and the wire (`latency` in
    /// `/v1/status`).
    pub wire: Mutex<WireTimes>,
}

/// The stages of [`WireTimes`], as `/v1/status` names them.
pub const WIRE_STAGES: [&str; 4] = ["handoff", "retarget", "send", "glass_to_wire"];

/// Where a subject's frames' time goes between its source and the wire, over the last
/// frames: `handoff` (the source's pose handed to the engine → the tick that takes it
/// starts), `retarget` (that tick's performers: mapping, foot lock), `send` (encoded → written
/// to a client's socket) and `glass_to_wire` (the frame's capture time → written). Each frame
/// (a new capture time) counts once: at the first tick that encodes it and at the first write
/// that carries it, so the ticks that repeat a frame and the slower of several clients do
/// not count. Fixed-size rings: recording allocates nothing.
#[derive(Debug, Default)]
pub struct WireTimes {
    times: StageTimes<{ WIRE_STAGES.len() }>,
    /// Capture time of the last frame counted at a tick, and at a write.
    ticked: u64,
    sent: u64,
}

impl WireTimes {
    /// The tick that started at `tick_start` encoded, at `encoded`, the frame captured at
    /// `capture` whose pose was handed over at `published` (0: not timed). Unix ns.
    pub fn ticked(&mut self, capture: u64, published: u64, tick_start: u64, encoded: u64) {
        if capture == 0 || published == 0 || capture <= self.ticked {
            return;
        }
        self.ticked = capture;
        // A pose handed over during the tick, after it started, waited for nothing.
        self.times
            .record_stage(0, tick_start.saturating_sub(published));
        self.times
            .record_stage(1, encoded.saturating_sub(tick_start));
    }

    /// A client's socket took, at `written`, the frame captured at `capture` and encoded at
    /// `encoded`. Unix ns.
    pub fn sent(&mut self, capture: u64, encoded: u64, written: u64) {
        if capture == 0 || capture <= self.sent {
            return;
        }
        self.sent = capture;
        self.times.record_stage(2, written.saturating_sub(encoded));
        self.times.record_stage(3, written.saturating_sub(capture));
    }

    /// p50/p99 of every stage measured so far.
    pub fn report(&self) -> Vec<StageLatency> {
        self.times.report(&WIRE_STAGES)
    }
}

impl SubjectStats {
    /// Counts a pose refused at `now` and keeps why.
    pub fn reject_pose(
        &self,
        refusal: rigcast_retarget::bounds::PoseRefusal,
        bone_name: &str,
        now: Instant,
    ) {
        self.rejected_poses.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut last) = self.last_rejection.lock() {
            *last = Some(format!("bone {bone_name}: {}", refusal.fault));
        }
        if let Ok(mut at) = self.last_rejection_at.lock() {
            *at = Some(now);
        }
    }

    /// Why poses are being refused, while one was in the `within` before `now`.
    pub fn recent_rejection(&self, within: Duration, now: Instant) -> Option<String> {
        let at = (*self.last_rejection_at.lock().ok()?)?;
        if now.saturating_duration_since(at) > within {
            return None;
        }
        let why = self.last_rejection.lock().ok()?.clone()?;
        Some(format!("poses refused ({why})"))
    }

    /// The current fault, if any.
    pub fn fault(&self) -> Option<String> {
        self.fault.lock().ok().and_then(|f| f.clone())
    }
}

/// A [`TargetMotion`] the tick stores without locking or allocating.
#[derive(Debug, Default)]
pub struct MotionCell(std::sync::atomic::AtomicU8);

const MOTIONS: [TargetMotion; 5] = [
    TargetMotion::Live,
    TargetMotion::Resuming,
    TargetMotion::Rest,
    TargetMotion::Hold,
    TargetMotion::IdleGraph,
];

impl MotionCell {
    /// Stores `m`.
    pub fn store(&self, m: TargetMotion) {
        let i = MOTIONS.iter().position(|x| *x == m).unwrap_or(0);
        self.0.store(i as u8, std::sync::atomic::Ordering::Relaxed);
    }

    /// The last stored motion (`live` before any).
    pub fn load(&self) -> TargetMotion {
        let i = self.0.load(std::sync::atomic::Ordering::Relaxed) as usize;
        MOTIONS.get(i).copied().unwrap_or(TargetMotion::Live)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rate_is_measured_on_the_times_given() {
        let m = RateMeter::default();
        let t0 = Instant::now();
        assert_eq!(m.rate_hz(t0), 0.0);
        // 30 events a second for 2 s, from the first one.
        for i in 0..60u32 {
            m.tick(t0 + Duration::from_secs(1) * i / 30);
        }
        assert!((m.rate_hz(t0 + Duration::from_secs(2)) - 30.0).abs() < 1e-9);
        // Read again within 0.5 s: the same figure; after 1 s without events: none.
        assert!((m.rate_hz(t0 + Duration::from_millis(2200)) - 30.0).abs() < 1e-9);
        assert_eq!(m.rate_hz(t0 + Duration::from_secs(3)), 0.0);
        assert_eq!(m.total(), 60);
    }

    #[test]
    fn each_frame_counts_once_at_its_first_tick_and_first_write() {
        const MS: u64 = 1_000_000;
        let mut w = WireTimes::default();
        assert!(w.report().is_empty());
        // Frame captured at 100 ms, handed over at 130, taken by the tick of 135 (performers
        // done at 137), written at 138 and, to a slower client, at 150.
        w.ticked(100 * MS, 130 * MS, 135 * MS, 137 * MS);
        w.sent(100 * MS, 137 * MS, 138 * MS);
        w.sent(100 * MS, 137 * MS, 150 * MS);
        // The next tick repeats the same frame: not counted again.
        w.ticked(100 * MS, 130 * MS, 152 * MS, 153 * MS);
        w.sent(100 * MS, 153 * MS, 154 * MS);
        // A frame handed over while the tick that takes it was running waited for nothing.
        w.ticked(133 * MS, 170 * MS, 169 * MS, 171 * MS);
        // A frame no live source handed over (a replay, a fallback pose) is not timed, and
        // neither is one without a capture time.
        w.ticked(166 * MS, 0, 185 * MS, 186 * MS);
        w.ticked(0, 1, 2, 3);
        w.sent(0, 1, 2);
        let r = w.report();
        let get = |name: &str| r.iter().find(|s| s.stage == name).unwrap();
        assert_eq!(get("handoff").samples, 2);
        assert_eq!(get("handoff").p99_ms, 5.0);
        let mut late = WireTimes::default();
        late.ticked(133 * MS, 170 * MS, 169 * MS, 171 * MS);
        assert_eq!(late.report()[0].p99_ms, 0.0);
        assert_eq!(get("retarget").samples, 2);
        assert_eq!(get("retarget").p99_ms, 2.0);
        assert_eq!((get("send").samples, get("send").p50_ms), (1, 1.0));
        assert_eq!(get("glass_to_wire").p50_ms, 38.0);
    }
}
