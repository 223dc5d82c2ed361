//! `Clip`: a skeleton with a sequence of poses at a fixed frame time — what animation files
//! decode into and what replay and offline retargeting consume.

use std::sync::Arc;

use crate::error::RetargetError;
use crate::pose::Pose;
use crate::skeleton::Skeleton;

/// An animation clip: fixed-rate poses on one skeleton.
#[derive(Debug, Clone)]
pub struct Clip {
    /// Clip name (file stem or animation name).
    pub name: String,
    /// The skeleton the poses belong to.
    pub skeleton: Arc<Skeleton>,
    /// One pose per frame. May be empty for a skeleton-only file.
    pub poses: Vec<Pose>,
    /// Seconds between frames.
    pub frame_time_secs: f64,
}

impl Clip {
    /// Builds a clip, checking every pose against the skeleton and the frame time.
    pub fn new(
        name: impl Into<String>,
        skeleton: Arc<Skeleton>,
        mut poses: Vec<Pose>,
        frame_time_secs: f64,
    ) -> Result<Clip, RetargetError> {
        if !(frame_time_secs.is_finite() && frame_time_secs > 0.0) {
            return Err(RetargetError::BadFrameTime { frame_time_secs });
        }
        for (frame, p) in poses.iter_mut().enumerate() {
            p.check(&skeleton)?;
            p.check_values().map_err(|r| RetargetError::BadPose {
                frame,
                bone: r.bone,
                fault: r.fault,
            })?;
        }
        Ok(Clip {
            name: name.into(),
            skeleton,
            poses,
            frame_time_secs,
        })
    }

    /// Number of frames.
    pub fn num_frames(&self) -> usize {
        self.poses.len()
    }

    /// Frames per second.
    pub fn fps(&self) -> f64 {
        1.0 / self.frame_time_secs
    }

    /// Duration in seconds from the first to one frame past the last
    /// (`num_frames × frame_time`), the convention BVH and most players use.
    pub fn duration_secs(&self) -> f64 {
        self.poses.len() as f64 * self.frame_time_secs
    }

    /// Samples the clip at `time_secs` (clamped to the clip) into `out`, interpolating between
    /// neighbouring frames. Allocates nothing. Returns the index of the frame at or before the
    /// time, or `None` when the clip has no frames (then `out` is untouched).
    pub fn sample_into(&self, time_secs: f64, out: &mut Pose) -> Option<usize> {
        let n = self.poses.len();
        if n == 0 {
            return None;
        }
        let f = (time_secs / self.frame_time_secs).max(0.0);
        let i = (f.floor() as usize).min(n - 1);
        let j = (i + 1).min(n - 1);
        let t = if i == j { 0.0 } else { (f - i as f64) as f32 };
        if t <= 0.0 {
            out.copy_from(&self.poses[i]);
        } else {
            out.interpolate_into(&self.poses[i], &self.poses[j], t.min(1.0));
        }
        Some(i)
    }

    /// A copy resampled to a new frame time (same duration, interpolated poses).
    pub fn resampled(&self, frame_time_secs: f64) -> Result<Clip, RetargetError> {
        if !(frame_time_secs.is_finite() && frame_time_secs > 0.0) {
            return Err(RetargetError::BadFrameTime { frame_time_secs });
        }
        if self.poses.is_empty() {
            return Clip::new(
                self.name.clone(),
                self.skeleton.clone(),
                Vec::new(),
                frame_time_secs,
            );
        }
        let last_time = (self.poses.len() - 1) as f64 * self.frame_time_secs;
        let wanted = (last_time / frame_time_secs + 1e-9).floor() + 1.0;
        let num_bones = self.skeleton.num_bones();
        let input_samples = (self.poses.len() * num_bones) as u64;
        let count = crate::bounds::frames_within_budget(wanted, num_bones, input_samples).ok_or(
            RetargetError::TooManyFrames {
                num_frames: wanted,
                num_bones,
                max_samples: crate::bounds::sample_budget(input_samples),
            },
        )?;
        let mut poses = Vec::with_capacity(count);
        let mut scratch = self.poses[0].clone();
        for k in 0..count {
            self.sample_into(k as f64 * frame_time_secs, &mut scratch);
            poses.push(scratch.clone());
        }
        Clip::new(
            self.name.clone(),
            self.skeleton.clone(),
            poses,
            frame_time_secs,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::{RawSkeleton, Transform};
    use glam::{Quat, Vec3};

    fn clip() -> Clip {
        let mut raw = RawSkeleton::default();
        let r = raw.add("root", None, Transform::IDENTITY);
        raw.add("tip", Some(r), Transform::from_translation(Vec3::Y));
        let s = Arc::new(Skeleton::build(&raw).expect("valid"));
        let mut a = s.rest_pose();
        let mut b = s.rest_pose();
        a.translations[0] = Vec3::ZERO;
        b.translations[0] = Vec3::new(2.0, 0.0, 0.0);
        b.rotations[1] = Quat::from_rotation_z(1.0);
        Clip::new("t", s, vec![a, b], 0.5).expect("valid")
    }

    #[test]
    fn samples_between_frames() {
        let c = clip();
        let mut out = c.skeleton.rest_pose();
        assert_eq!(c.sample_into(0.25, &mut out), Some(0));
        assert!((out.translations[0].x - 1.0).abs() < 1e-6);
        assert!((out.rotations[1].to_axis_angle().1 - 0.5).abs() < 1e-5);
        assert_eq!(c.sample_into(10.0, &mut out), Some(1));
        assert!((out.translations[0].x - 2.0).abs() < 1e-6);
        assert!((c.duration_secs() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn resample_keeps_span() {
        let c = clip().resampled(0.1).expect("valid");
        assert_eq!(c.num_frames(), 6);
        assert!((c.poses[5].translations[0].x - 2.0).abs() < 1e-5);
        assert!(Clip::new("x", clip().skeleton, vec![], 0.0).is_err());
    }
}
