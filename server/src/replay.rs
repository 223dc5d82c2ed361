//! Turns a [`Clip`] into a timed pose stream: which clip frame to show after `elapsed` seconds
//! of wall clock, honouring speed, looping and a start offset.
//!
//! The source task samples only at exact frame times (elapsed is snapped to the frame grid), so
//! streamed rotations equal the file's frames bit-for-bit modulo float rounding, which tests rely
//! on.

use rigcast_retarget::{Clip, Pose};

use crate::config::ReplaySettings;

/// A clip plus playback settings.
#[derive(Debug, Clone)]
pub struct ClipPlayer {
    clip: Clip,
    settings: ReplaySettings,
}

impl ClipPlayer {
    /// Wraps a clip. Speed must be positive (validated by the config).
    pub fn new(clip: Clip, settings: ReplaySettings) -> ClipPlayer {
        ClipPlayer { clip, settings }
    }

    /// The clip.
    pub fn clip(&self) -> &Clip {
        &self.clip
    }

    /// Wall-clock seconds between two clip frames at this speed.
    pub fn frame_period_secs(&self) -> f64 {
        self.clip.frame_time_secs / self.settings.speed
    }

    /// Writes the pose of clip frame number `k` since start (looping or clamped) into `out`.
    /// Returns the clip frame index, or `None` once a non-looping clip has ended or when the
    /// clip has no frames.
    pub fn frame_into(&self, k: u64, out: &mut Pose) -> Option<usize> {
        let n = self.clip.num_frames() as u64;
        if n == 0 {
            return None;
        }
        let offset = (self.settings.start_offset_secs / self.clip.frame_time_secs).round() as u64;
        let index = k.saturating_add(offset);
        let index = if self.settings.looping {
            index % n
        } else if index < n {
            index
        } else {
            return None;
        };
        let i = index as usize;
        out.copy_from(&self.clip.poses[i]);
        Some(i)
    }
}
