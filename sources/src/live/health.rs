//! `HealthTracker`: turns input/frame events into a [`SourceStatus`] (state machine, rate,
//! latency), shared by every live source so they report health the same way.

use std::time::{Duration, Instant};

use super::{FrameMeta, SourceState, SourceStatus};

/// Rate is recomputed over windows of at least this length, so a few jittery packets don't
/// make the reported fps jump around.
const RATE_WINDOW: Duration = Duration::from_millis(500);

/// Tracks a live source's state, input rate, latency and counters.
///
/// State machine: `Connecting` until the first good input; `Live` while good input keeps
/// arriving within `lost_after`; `Lost` after silence or a device error; back to `Live` on the
/// next good input.
#[derive(Debug, Clone)]
pub struct HealthTracker {
    state: SourceState,
    lost_after: Duration,
    last_input: Option<Instant>,
    frames: u64,
    dropped: u64,
    window_start: Instant,
    window_frames: u32,
    input_fps: f32,
    latency_ms: f32,
    detail: String,
}

impl HealthTracker {
    /// A tracker in the `Connecting` state; silence longer than `lost_after` means `Lost`.
    pub fn new(lost_after: Duration) -> Self {
        HealthTracker {
            state: SourceState::Connecting,
            lost_after,
            last_input: None,
            frames: 0,
            dropped: 0,
            window_start: Instant::now(),
            window_frames: 0,
            input_fps: 0.0,
            latency_ms: 0.0,
            detail: String::new(),
        }
    }

    /// Good (decodable) input arrived at `now`: the source is live.
    pub fn on_input(&mut self, now: Instant) {
        self.last_input = Some(now);
        if self.state == SourceState::Lost {
            // The detail said why the input was lost; it is back, so that no longer holds.
            self.detail.clear();
        }
        self.state = SourceState::Live;
    }

    /// A frame was produced; `latency` is input arrival (or capture) → frame returned.
    pub fn on_frame(&mut self, now: Instant, latency: Duration) {
        self.frames += 1;
        self.window_frames += 1;
        let ms = latency.as_secs_f32() * 1000.0;
        // Exponential smoothing: steady enough to read, quick enough to show a change.
        self.latency_ms = if self.frames == 1 {
            ms
        } else {
            0.9 * self.latency_ms + 0.1 * ms
        };
        self.update_rate(now);
    }

    /// A frame was produced from input that arrived at `arrived`: counts it (latency is
    /// `arrived` → now) and returns its [`FrameMeta`]. The sequence number is the count of frames
    /// produced, so every source numbers 1, 2, 3, …; the first frame always reports a skeleton
    /// change, `skeleton_changed` adds the source's own later changes.
    pub fn produced(
        &mut self,
        arrived: Instant,
        capture_nanos: u64,
        skeleton_changed: bool,
    ) -> FrameMeta {
        let now = Instant::now();
        self.on_frame(now, now.saturating_duration_since(arrived));
        FrameMeta {
            seq: self.frames,
            capture_nanos,
            skeleton_changed: skeleton_changed || self.frames == 1,
        }
    }

    /// `n` input units were dropped (malformed, reordered, unusable).
    pub fn on_dropped(&mut self, n: u64) {
        self.dropped += n;
    }

    /// The device went away (port unplugged, socket error): `Lost` at once.
    pub fn on_device_lost(&mut self, detail: impl Into<String>) {
        if self.state != SourceState::Connecting {
            self.state = SourceState::Lost;
        }
        self.detail = detail.into();
    }

    /// The input is known to be gone for good (what feeds it stopped existing): `Lost` even if
    /// it never arrived, unlike [`HealthTracker::on_device_lost`].
    pub fn on_gone(&mut self, detail: impl Into<String>) {
        self.state = SourceState::Lost;
        self.detail = detail.into();
    }

    /// Sets the detail text (allocates only if it differs).
    pub fn set_detail(&mut self, detail: &str) {
        if self.detail != detail {
            self.detail.clear();
            self.detail.push_str(detail);
        }
    }

    /// Re-evaluates silence at `now`; call this whenever a wait times out.
    pub fn poll(&mut self, now: Instant) {
        if let Some(last) = self.last_input {
            if self.state == SourceState::Live && now.duration_since(last) > self.lost_after {
                self.state = SourceState::Lost;
            }
        }
        self.update_rate(now);
    }

    /// Current state.
    pub fn state(&self) -> SourceState {
        self.state
    }

    /// Frames produced so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Inputs dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Snapshot for reporting (allocates the detail string).
    pub fn status(&self) -> SourceStatus {
        SourceStatus {
            state: self.state,
            input_fps: self.input_fps,
            latency_ms: self.latency_ms,
            frames: self.frames,
            dropped: self.dropped,
            detail: self.detail.clone(),
            camera: None,
        }
    }

    fn update_rate(&mut self, now: Instant) {
        let elapsed = now.saturating_duration_since(self.window_start);
        if elapsed >= RATE_WINDOW {
            self.input_fps = self.window_frames as f32 / elapsed.as_secs_f32();
            self.window_frames = 0;
            self.window_start = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connecting_live_lost_live() {
        let t0 = Instant::now();
        let mut h = HealthTracker::new(Duration::from_millis(500));
        assert_eq!(h.state(), SourceState::Connecting);
        // Silence before any input keeps Connecting (there was never a sender).
        h.poll(t0 + Duration::from_secs(2));
        assert_eq!(h.state(), SourceState::Connecting);
        h.on_input(t0);
        assert_eq!(h.state(), SourceState::Live);
        h.poll(t0 + Duration::from_millis(400));
        assert_eq!(h.state(), SourceState::Live);
        h.poll(t0 + Duration::from_millis(600));
        assert_eq!(h.state(), SourceState::Lost);
        h.on_input(t0 + Duration::from_millis(700));
        assert_eq!(h.state(), SourceState::Live);
        h.on_device_lost("unplugged");
        assert_eq!(h.state(), SourceState::Lost);
        assert_eq!(h.status().detail, "unplugged");
    }

    #[test]
    fn rate_counts_frames_per_window() {
        let mut h = HealthTracker::new(Duration::from_millis(500));
        let t0 = h.window_start;
        for i in 0..30 {
            h.on_frame(t0 + Duration::from_millis(i * 1000 / 60), Duration::ZERO);
        }
        h.poll(t0 + Duration::from_millis(500));
        // 30 frames in 0.5 s.
        assert!(
            (h.status().input_fps - 60.0).abs() < 1.0,
            "{}",
            h.status().input_fps
        );
        assert_eq!(h.frames(), 30);
    }

    #[test]
    fn produced_numbers_frames_and_flags_the_first_skeleton() {
        let mut h = HealthTracker::new(Duration::from_millis(500));
        let a = h.produced(Instant::now(), 7, false);
        let b = h.produced(Instant::now(), 8, false);
        let c = h.produced(Instant::now(), 9, true);
        assert_eq!((a.seq, a.capture_nanos, a.skeleton_changed), (1, 7, true));
        assert_eq!((b.seq, b.capture_nanos, b.skeleton_changed), (2, 8, false));
        assert_eq!((c.seq, c.skeleton_changed), (3, true));
        assert_eq!(h.frames(), 3);
    }
}
