//! [`VisionSource`]: a [`FrameSource`] plus the [`PosePipeline`], served as a
//! [`LiveSource`](crate::live::LiveSource) on the BlazePose skeleton.
//!
//! Frames of a file can be paced to their timestamps (real-time playback, as a webcam would
//! deliver them) or served as fast as they decode.
//!
//! The raw tap receives one [`RawKind::Landmarks`] record per processed frame: the model's raw
//! landmarks (before smoothing, see [`encode_landmarks`]) when a person was found, an empty
//! record when none was. Its time is the frame's timestamp anchored to the wall clock at the
//! first frame, so the intervals are exactly the ones the smoothing saw. That is everything
//! [`LandmarkReplaySource`](super::LandmarkReplaySource) needs to reproduce the session's poses.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_retarget::{Pose, Skeleton};

use super::error::VisionError;
use super::frame::{FrameSource, RgbFrame};
use super::landmarks::{Landmarks, NUM_MODEL_LANDMARKS};
use super::pipeline::PosePipeline;
use crate::live::{
    unix_nanos_now, wait_until, HealthTracker, LiveSource, NextFrame, Pace, RawKind, RawTap,
    SourceError, SourceStatus,
};

/// Bytes of one landmark record: presence, then 39 × (x, y, z, visibility) image values,
/// 39 × (x, y, z) world values and the picture's width and height, all little-endian f32.
pub const LANDMARK_RECORD_BYTES: usize = PICTURELESS_RECORD_BYTES + 8;

/// Bytes of a record written before the picture's size was kept (read with it unknown).
pub const PICTURELESS_RECORD_BYTES: usize = 4 * (1 + NUM_MODEL_LANDMARKS * 7);

/// Encodes landmarks as a raw record (little-endian f32s) into `out` (cleared first).
pub fn encode_landmarks(lm: &Landmarks, out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&lm.presence.to_le_bytes());
    for v in &lm.image {
        for c in v.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for v in &lm.world {
        for c in v.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for c in lm.picture.to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

/// Decodes a record written by [`encode_landmarks`] (or one without the picture's size, from
/// before it was kept); `None` when the length is neither.
pub fn decode_landmarks(bytes: &[u8]) -> Option<Landmarks> {
    if bytes.len() != LANDMARK_RECORD_BYTES && bytes.len() != PICTURELESS_RECORD_BYTES {
        return None;
    }
    let mut vals = bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]));
    let mut lm = Landmarks {
        presence: vals.next()?,
        ..Landmarks::default()
    };
    for v in lm.image.iter_mut() {
        *v = glam::Vec4::new(vals.next()?, vals.next()?, vals.next()?, vals.next()?);
    }
    for v in lm.world.iter_mut() {
        *v = glam::Vec3::new(vals.next()?, vals.next()?, vals.next()?);
    }
    if let (Some(w), Some(h)) = (vals.next(), vals.next()) {
        // A recording is untrusted: a size no camera gives (or not a number) is read as
        // unknown, which leaves the perspective stage off rather than feeding it absurd values.
        let side = 0.0..=super::camera_modes::MAX_SIDE as f32;
        if side.contains(&w) && side.contains(&h) {
            lm.picture = glam::Vec2::new(w, h);
        }
    }
    Some(lm)
}

/// The raw tap of a vision source and the landmark record it is fed (see the module doc).
pub(crate) struct LandmarkTap {
    tap: Option<Box<dyn RawTap>>,
    record: Vec<u8>,
    /// Wall-clock nanoseconds of frame time 0 (set at the first frame), for frame times.
    anchor_nanos: Option<u64>,
}

impl LandmarkTap {
    /// No tap yet; the record's buffer is allocated here, not per frame.
    pub(crate) fn new() -> LandmarkTap {
        LandmarkTap {
            tap: None,
            record: Vec::with_capacity(LANDMARK_RECORD_BYTES),
            anchor_nanos: None,
        }
    }

    /// Installs (or removes) the tap.
    pub(crate) fn set(&mut self, tap: Option<Box<dyn RawTap>>) {
        self.tap = tap;
    }

    /// Hands the tap one record at `capture_nanos`: `landmarks`, or an empty record when no
    /// person was found.
    pub(crate) fn record(&mut self, landmarks: Option<&Landmarks>, capture_nanos: u64) {
        if let Some(tap) = self.tap.as_mut() {
            match landmarks {
                Some(lm) => encode_landmarks(lm, &mut self.record),
                None => self.record.clear(),
            }
            tap.raw(RawKind::Landmarks, capture_nanos, &self.record);
        }
    }

    /// [`LandmarkTap::record`] at frame time `frame_secs`, anchored to the wall clock
    /// `capture_nanos` of the first frame recorded.
    pub(crate) fn record_frame(
        &mut self,
        landmarks: Option<&Landmarks>,
        frame_secs: f64,
        capture_nanos: u64,
    ) {
        if self.tap.is_none() {
            return;
        }
        let frame_nanos = (frame_secs.max(0.0) * 1e9).round() as u64;
        let anchor = *self
            .anchor_nanos
            .get_or_insert_with(|| capture_nanos.saturating_sub(frame_nanos));
        self.record(landmarks, anchor + frame_nanos);
    }
}

fn source_error(e: VisionError) -> SourceError {
    SourceError::Stream(std::io::Error::other(e))
}

/// Webcam or video → BlazePose → poses, as a live source.
pub struct VisionSource {
    name: String,
    frames: Box<dyn FrameSource>,
    pipeline: PosePipeline,
    frame: RgbFrame,
    pending: bool,
    ended: bool,
    /// Set when frames are released at their timestamps.
    pace: Option<Pace>,
    health: HealthTracker,
    tap: LandmarkTap,
}

debug_fields!(VisionSource { name });

impl VisionSource {
    /// Serves `frames` through `pipeline`. With `realtime`, frames are released at their
    /// timestamps (wall clock from the first frame); otherwise as fast as they are processed.
    pub fn new(
        name: impl Into<String>,
        frames: Box<dyn FrameSource>,
        pipeline: PosePipeline,
        realtime: bool,
    ) -> VisionSource {
        let (w, h) = frames.size();
        VisionSource {
            name: name.into(),
            frames,
            pipeline,
            frame: RgbFrame::new(w, h),
            pending: false,
            ended: false,
            pace: realtime.then(Pace::default),
            health: HealthTracker::new(Duration::from_secs(1)),
            tap: LandmarkTap::new(),
        }
    }

    /// The pipeline (confidence, stats).
    pub fn pipeline(&self) -> &PosePipeline {
        &self.pipeline
    }
}

impl LiveSource for VisionSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn skeleton(&self) -> Option<Arc<Skeleton>> {
        Some(self.pipeline.skeleton().clone())
    }

    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame {
        let call_start = Instant::now();
        if self.ended {
            self.health.poll(call_start);
            std::thread::sleep(timeout);
            return Ok(None);
        }
        if !self.pending {
            match self.frames.next_frame(&mut self.frame) {
                Ok(true) => self.pending = true,
                Ok(false) => {
                    self.ended = true;
                    self.health.on_device_lost("end of input");
                    return Ok(None);
                }
                Err(e) => {
                    self.health.on_device_lost(e.to_string());
                    return Err(source_error(e));
                }
            }
        }
        let arrived = Instant::now();
        if let Some(pace) = self.pace.as_mut() {
            if !wait_until(
                pace.due(self.frame.time_secs, arrived),
                call_start + timeout,
            ) {
                return Ok(None);
            }
        }
        self.pending = false;
        let capture_nanos = unix_nanos_now();
        let found = self
            .pipeline
            .process(&self.frame, out)
            .map_err(source_error)?
            .is_some();
        let raw = found.then(|| self.pipeline.raw_landmarks());
        self.tap
            .record_frame(raw, self.frame.time_secs, capture_nanos);
        self.health.on_input(Instant::now());
        if !found {
            self.health.set_detail("no person in view");
            return Ok(None);
        }
        // The skeleton is fixed (BlazePose), so only the first frame announces it.
        Ok(Some(self.health.produced(arrived, capture_nanos, false)))
    }

    fn status(&self) -> SourceStatus {
        self.health.status()
    }

    fn set_raw_tap(&mut self, tap: Option<Box<dyn RawTap>>) {
        self.tap.set(tap);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn landmark_records_round_trip() {
        let mut lm = Landmarks {
            presence: 0.75,
            ..Landmarks::default()
        };
        lm.image[3] = glam::Vec4::new(1.0, 2.0, 3.0, 0.5);
        lm.world[38] = glam::Vec3::new(-0.1, 0.2, 0.3);
        lm.picture = glam::Vec2::new(1080.0, 1920.0);
        let mut bytes = Vec::new();
        encode_landmarks(&lm, &mut bytes);
        assert_eq!(bytes.len(), LANDMARK_RECORD_BYTES);
        assert_eq!(decode_landmarks(&bytes), Some(lm));
        assert_eq!(decode_landmarks(&bytes[1..]), None);
        // A record from before the picture's size was kept: the same, the size unknown.
        let old = &bytes[..PICTURELESS_RECORD_BYTES];
        let read = decode_landmarks(old).unwrap();
        assert_eq!(read.picture, glam::Vec2::ZERO);
        // A size no camera gives (from a hostile file) is read as unknown.
        for bad in [f32::NAN, -1.0, 1e30] {
            let mut wild = bytes.clone();
            let at = PICTURELESS_RECORD_BYTES;
            wild[at..at + 4].copy_from_slice(&bad.to_le_bytes());
            assert_eq!(decode_landmarks(&wild).unwrap().picture, glam::Vec2::ZERO);
        }
        assert_eq!(read.world, lm.world);
        assert_eq!(read.image, lm.image);
    }
}
