//! [`LandmarkReplaySource`]: hardware-free replay of a recorded vision session.
//!
//! A live [`VisionSource`](super::VisionSource) with a raw tap records, per video frame, the
//! model's raw landmarks (see [`encode_landmarks`](super::source::encode_landmarks)) or an
//! empty "no person" marker. Replaying those records through the same [`LandmarkStages`]
//! (smoothing → constant lengths → rotations) at the recorded times reproduces the live poses
//! and per-bone confidences, with no model, runtime or camera. Committed example:
//! `recordings/vision/pose2sim_cam01.rcr`.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_retarget::{Pose, Skeleton};

use super::error::VisionError;
use super::landmarks::Landmarks;
use super::pipeline::PipelineConfig;
use super::source::{
    decode_landmarks, LandmarkTap, LANDMARK_RECORD_BYTES, PICTURELESS_RECORD_BYTES,
};
use super::stages::LandmarkStages;
use crate::live::{
    unix_nanos_now, wait_until, HealthTracker, LiveSource, NextFrame, Pace, RawKind, RawTap,
    SourceStatus,
};
use crate::recording::{read_recording, RawPacket};

/// One recorded video frame: its time and the model's landmarks (`None` = no person).
#[derive(Debug, Clone, Copy)]
struct Entry {
    capture_nanos: u64,
    landmarks: Option<Landmarks>,
}

/// Recorded landmark records served as a live source on the BlazePose skeleton.
pub struct LandmarkReplaySource {
    name: String,
    stages: LandmarkStages,
    entries: Vec<Entry>,
    next: usize,
    malformed: u64,
    /// Set when frames are released at their recorded pace.
    pace: Option<Pace>,
    health: HealthTracker,
    tap: LandmarkTap,
}

debug_fields!(LandmarkReplaySource { name, entries.len(), next });

impl LandmarkReplaySource {
    /// Reads the landmark records of `path` (only those of `source_id`, when given). The
    /// smoothing and solver settings come from `config` (assets and model are not used).
    /// With `realtime`, frames are released at their recorded pace.
    pub fn open(
        path: &Path,
        source_id: Option<u32>,
        config: &PipelineConfig,
        realtime: bool,
    ) -> Result<LandmarkReplaySource, VisionError> {
        let fail = |message: String| VisionError::Recording {
            path: path.display().to_string(),
            message,
        };
        let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
        let rec = read_recording(std::io::BufReader::new(file)).map_err(|e| fail(e.to_string()))?;
        let packets = rec
            .raw
            .iter()
            .filter(|p| source_id.is_none_or(|id| p.source_id == id));
        let name = format!("replay:{}", path.display());
        LandmarkReplaySource::from_packets(name, packets, config, realtime)
            .map_err(|e| fail(e.to_string()))
    }

    /// Serves the landmark packets among `packets` (other kinds are ignored). Records of the
    /// wrong length are counted in [`SourceStatus::dropped`] and skipped.
    pub fn from_packets<'a>(
        name: impl Into<String>,
        packets: impl IntoIterator<Item = &'a RawPacket>,
        config: &PipelineConfig,
        realtime: bool,
    ) -> Result<LandmarkReplaySource, VisionError> {
        let mut entries = Vec::new();
        let mut malformed = 0;
        for p in packets.into_iter().filter(|p| p.kind == RawKind::Landmarks) {
            let landmarks = if p.bytes.is_empty() {
                None
            } else if let Some(lm) = decode_landmarks(&p.bytes) {
                Some(lm)
            } else {
                malformed += 1;
                continue;
            };
            entries.push(Entry {
                capture_nanos: p.capture_nanos,
                landmarks,
            });
        }
        if entries.is_empty() {
            return Err(VisionError::Recording {
                path: name.into(),
                message: format!(
                    "no landmark records (raw kind 2, {LANDMARK_RECORD_BYTES} or \
                     {PICTURELESS_RECORD_BYTES} bytes, or empty); \
                     {malformed} of the wrong length"
                ),
            });
        }
        let mut health = HealthTracker::new(Duration::from_secs(1));
        health.on_dropped(malformed);
        Ok(LandmarkReplaySource {
            name: name.into(),
            stages: config.stages()?,
            entries,
            next: 0,
            malformed,
            pace: realtime.then(Pace::default),
            health,
            tap: LandmarkTap::new(),
        })
    }

    /// Recorded video frames (with or without a person).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when the recording held no usable frames (never, once built).
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// True once every recorded frame has been served.
    pub fn finished(&self) -> bool {
        self.next >= self.entries.len()
    }

    /// Landmark records skipped for having the wrong length.
    pub fn malformed(&self) -> u64 {
        self.malformed
    }

    /// Per-bone confidence of the last solved frame.
    pub fn confidence(&self) -> &[f32] {
        self.stages.confidence()
    }

    /// Landmarks of the last solved frame after smoothing and constant lengths.
    pub fn landmarks(&self) -> &Landmarks {
        self.stages.smoothed()
    }

    /// Seconds of frame `i` from the first recorded frame.
    fn time_secs(&self, i: usize) -> f64 {
        let first = self.entries[0].capture_nanos;
        self.entries[i].capture_nanos.saturating_sub(first) as f64 * 1e-9
    }
}

impl LiveSource for LandmarkReplaySource {
    fn name(&self) -> &str {
        &self.name
    }

    fn skeleton(&self) -> Option<Arc<Skeleton>> {
        Some(self.stages.skeleton().clone())
    }

    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame {
        let call_start = Instant::now();
        let Some(entry) = self.entries.get(self.next).copied() else {
            if self.health.state() != crate::live::SourceState::Lost {
                self.health.on_device_lost("end of recording");
                return Ok(None);
            }
            self.health.poll(call_start);
            std::thread::sleep(timeout);
            return Ok(None);
        };
        let t = self.time_secs(self.next);
        if let Some(pace) = self.pace.as_mut() {
            if !wait_until(pace.due(t, call_start), call_start + timeout) {
                return Ok(None);
            }
        }
        self.next += 1;
        let arrived = Instant::now();
        let capture_nanos = unix_nanos_now();
        self.tap
            .record(entry.landmarks.as_ref(), entry.capture_nanos);
        self.health.on_input(arrived);
        let Some(lm) = entry.landmarks else {
            // Exactly what the live pipeline does when the tracker loses the person.
            self.stages.lost();
            self.health.set_detail("no person in view");
            return Ok(None);
        };
        self.stages.process(&lm, t, out);
        Ok(Some(self.health.produced(arrived, capture_nanos, false)))
    }

    fn status(&self) -> SourceStatus {
        self.health.status()
    }

    fn set_raw_tap(&mut self, tap: Option<Box<dyn RawTap>>) {
        self.tap.set(tap);
    }
}
