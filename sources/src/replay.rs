//! Replay: plays a [`Clip`] against a wall clock, as a source.
//!
//! ```text
//!  elapsed wall secs ──× speed + start offset──▶ clip time ──/ frame time──▶ frame index
//!                                                   (wraps when looping)
//! ```
//!
//! Synchronous and allocation-free per call: the caller drives the clock (the server's tick),
//! so tests can replay hours of footage instantly.

use std::sync::Arc;

use rigcast_retarget::{Clip, Pose, Skeleton};

use crate::error::SourceError;

/// How a [`Replay`] plays its clip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayOptions {
    /// Playback rate (1.0 = the clip's native timing; must be positive).
    pub speed: f64,
    /// Start over after the last frame.
    pub looping: bool,
    /// Clip time, in seconds, that plays at elapsed time 0 (must be ≥ 0).
    pub start_offset_secs: f64,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            speed: 1.0,
            looping: true,
            start_offset_secs: 0.0,
        }
    }
}

/// A clip played against elapsed wall-clock time.
#[derive(Debug, Clone)]
pub struct Replay {
    clip: Clip,
    opts: ReplayOptions,
}

impl Replay {
    /// Validates the options; the clip needs at least one frame.
    pub fn new(clip: Clip, opts: ReplayOptions) -> Result<Replay, SourceError> {
        if !(opts.speed.is_finite() && opts.speed > 0.0) {
            return Err(SourceError::InvalidOption {
                reason: format!("replay speed must be positive, got {}", opts.speed),
            });
        }
        if !(opts.start_offset_secs.is_finite() && opts.start_offset_secs >= 0.0) {
            return Err(SourceError::InvalidOption {
                reason: format!("start offset must be ≥ 0 s, got {}", opts.start_offset_secs),
            });
        }
        if clip.poses.is_empty() {
            return Err(SourceError::NoFrames {
                reason: format!("clip {:?} has no frames to replay", clip.name),
            });
        }
        Ok(Replay { clip, opts })
    }

    /// The skeleton the poses are on.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.clip.skeleton
    }

    /// The clip being played.
    pub fn clip(&self) -> &Clip {
        &self.clip
    }

    /// Seconds between the clip's frames (at speed 1).
    pub fn frame_time_secs(&self) -> f64 {
        self.clip.frame_time_secs
    }

    /// The frame index playing `elapsed_secs` after the start, or `None` once a non-looping
    /// replay has finished.
    pub fn frame_at(&self, elapsed_secs: f64) -> Option<usize> {
        let n = self.clip.poses.len();
        let clip_time = self.opts.start_offset_secs + elapsed_secs.max(0.0) * self.opts.speed;
        let f = (clip_time / self.clip.frame_time_secs + 1e-9).floor();
        if !f.is_finite() {
            return None;
        }
        // f ≥ 0; the float → integer conversion saturates, so huge times cannot overflow.
        let index = f as u64;
        if self.opts.looping {
            Some((index % n as u64) as usize)
        } else if index < n as u64 {
            Some(index as usize)
        } else {
            None
        }
    }

    /// Copies the pose playing at `elapsed_secs` into `out` (sized for [`Self::skeleton`]) and
    /// returns its frame index; `None` (and `out` untouched) when finished and not looping.
    /// Allocates nothing.
    pub fn sample(&self, elapsed_secs: f64, out: &mut Pose) -> Option<usize> {
        let i = self.frame_at(elapsed_secs)?;
        out.copy_from(&self.clip.poses[i]);
        Some(i)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use glam::Vec3;
    use rigcast_retarget::{RawSkeleton, Transform};

    fn clip(frames: usize, fps: f64) -> Clip {
        let mut raw = RawSkeleton::default();
        raw.add("root", None, Transform::IDENTITY);
        let s = Arc::new(Skeleton::build(&raw).unwrap());
        let poses = (0..frames)
            .map(|k| {
                let mut p = s.rest_pose();
                p.translations[0] = Vec3::X * k as f32;
                p
            })
            .collect();
        Clip::new("c", s, poses, 1.0 / fps).unwrap()
    }

    #[test]
    fn plays_at_native_timing_and_loops() {
        let r = Replay::new(clip(10, 10.0), ReplayOptions::default()).unwrap();
        let mut out = r.skeleton().rest_pose();
        assert_eq!(r.sample(0.0, &mut out), Some(0));
        assert_eq!(r.sample(0.35, &mut out), Some(3));
        assert_eq!(out.translations[0].x, 3.0);
        // Exactly on a frame boundary (float-noisy 0.3) still lands on that frame.
        assert_eq!(r.sample(0.1 + 0.2, &mut out), Some(3));
        assert_eq!(r.sample(1.05, &mut out), Some(0));
        assert_eq!(r.sample(2.95, &mut out), Some(9));
        assert_eq!(r.sample(1e30, &mut out).map(|i| i < 10), Some(true));
    }

    #[test]
    fn speed_offset_and_end() {
        let opts = ReplayOptions {
            speed: 2.0,
            looping: false,
            start_offset_secs: 0.2,
        };
        let r = Replay::new(clip(10, 10.0), opts).unwrap();
        let mut out = r.skeleton().rest_pose();
        assert_eq!(r.sample(0.0, &mut out), Some(2));
        assert_eq!(r.sample(0.2, &mut out), Some(6));
        assert_eq!(r.sample(0.39, &mut out), Some(9));
        out.translations[0].x = -1.0;
        assert_eq!(r.sample(0.41, &mut out), None);
        assert_eq!(out.translations[0].x, -1.0);
    }

    #[test]
    fn rejects_bad_options() {
        let bad_speed = ReplayOptions {
            speed: 0.0,
            ..Default::default()
        };
        assert!(Replay::new(clip(3, 10.0), bad_speed).is_err());
        let bad_offset = ReplayOptions {
            start_offset_secs: f64::NAN,
            ..Default::default()
        };
        assert!(Replay::new(clip(3, 10.0), bad_offset).is_err());
        assert!(matches!(
            Replay::new(clip(0, 10.0), ReplayOptions::default()),
            Err(SourceError::NoFrames { .. })
        ));
    }
}
