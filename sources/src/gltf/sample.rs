//! Keyframe sampling for glTF animation channels: LINEAR (slerp for rotations), STEP and
//! CUBICSPLINE (cubic Hermite with tangents scaled by the key interval, as the glTF spec says).

use glam::{Quat, Vec3, Vec4};

/// How values between keys are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Linear (spherical linear for rotations).
    Linear,
    /// Hold the previous key's value.
    Step,
    /// Cubic Hermite; outputs hold (in-tangent, value, out-tangent) per key.
    CubicSpline,
}

/// How a [`Track`] is malformed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TrackError {
    /// No key at all.
    #[error("animation sampler has no keys")]
    NoKeys,
    /// The output accessor does not hold one value (three for cubic splines) per key.
    #[error("sampler has {keys} keys but {values} output values (expected {expected})")]
    ValueCount {
        /// keys in the input accessor
        keys: usize,
        /// values in the output accessor
        values: usize,
        /// values the keys need
        expected: usize,
    },
    /// Key times that are not finite or go backwards.
    #[error("key times are not finite and non-decreasing")]
    TimeOrder,
}

/// One animated property: key times and values (`[in, value, out]` triples for cubic splines).
/// Values are stored as `Vec4` (translations use x, y, z).
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Key times in seconds, non-decreasing.
    pub times: Vec<f32>,
    /// Key values; three per key for [`Interpolation::CubicSpline`].
    pub values: Vec<Vec4>,
    /// Interpolation mode.
    pub interpolation: Interpolation,
}

impl Track {
    /// Checks the value count and time order.
    pub fn validate(&self) -> Result<(), TrackError> {
        let per_key = match self.interpolation {
            Interpolation::CubicSpline => 3,
            _ => 1,
        };
        if self.times.is_empty() {
            return Err(TrackError::NoKeys);
        }
        if self.values.len() != self.times.len() * per_key {
            return Err(TrackError::ValueCount {
                keys: self.times.len(),
                values: self.values.len(),
                expected: self.times.len() * per_key,
            });
        }
        if self.times.iter().any(|t| !t.is_finite()) || self.times.windows(2).any(|w| w[1] < w[0]) {
            return Err(TrackError::TimeOrder);
        }
        Ok(())
    }

    /// Time of the last key.
    pub fn end_secs(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }

    fn value(&self, key: usize) -> Vec4 {
        match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * key + 1],
            _ => self.values[key],
        }
    }

    /// Key index `i` and fraction `s` in `[0, 1)` with `times[i] ≤ t < times[i+1]`, or a clamp.
    fn locate(&self, t: f32) -> Locate {
        let n = self.times.len();
        if n == 1 || t <= self.times[0] {
            return Locate::Key(0);
        }
        if t >= self.times[n - 1] {
            return Locate::Key(n - 1);
        }
        // First key strictly after t; t is inside (times[0], times[n-1]) so 1 ≤ j ≤ n-1.
        let j = self.times.partition_point(|&k| k <= t);
        let i = j - 1;
        let dt = self.times[j] - self.times[i];
        if dt <= 0.0 {
            return Locate::Key(j);
        }
        Locate::Between(i, (t - self.times[i]) / dt, dt)
    }

    /// Samples as a 3-vector (translation / scale).
    pub fn sample_vec3(&self, t: f32) -> Vec3 {
        self.sample_raw(t, false).truncate()
    }

    /// Samples as a rotation (normalised).
    pub fn sample_quat(&self, t: f32) -> Quat {
        let v = self.sample_raw(t, true);
        Quat::from_vec4(v).normalize()
    }

    fn sample_raw(&self, t: f32, rotation: bool) -> Vec4 {
        match self.locate(t) {
            Locate::Key(k) => self.value(k),
            Locate::Between(i, s, dt) => match self.interpolation {
                Interpolation::Step => self.value(i),
                Interpolation::Linear => {
                    let (a, b) = (self.value(i), self.value(i + 1));
                    if rotation {
                        Vec4::from(Quat::from_vec4(a).slerp(Quat::from_vec4(b), s))
                    } else {
                        a.lerp(b, s)
                    }
                }
                Interpolation::CubicSpline => {
                    let p0 = self.values[3 * i + 1];
                    let m0 = self.values[3 * i + 2] * dt; // out-tangent of key i
                    let p1 = self.values[3 * (i + 1) + 1];
                    let m1 = self.values[3 * (i + 1)] * dt; // in-tangent of key i+1
                    let (s2, s3) = (s * s, s * s * s);
                    p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                        + m0 * (s3 - 2.0 * s2 + s)
                        + p1 * (-2.0 * s3 + 3.0 * s2)
                        + m1 * (s3 - s2)
                }
            },
        }
    }
}

enum Locate {
    Key(usize),
    Between(usize, f32, f32),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f32) -> Vec4 {
        Vec4::new(x, 0.0, 0.0, 0.0)
    }

    #[test]
    fn linear_step_and_clamp() {
        let mut tr = Track {
            times: vec![1.0, 2.0, 4.0],
            values: vec![v(0.0), v(10.0), v(30.0)],
            interpolation: Interpolation::Linear,
        };
        assert!(tr.validate().is_ok());
        assert_eq!(tr.sample_vec3(0.0).x, 0.0);
        assert_eq!(tr.sample_vec3(1.5).x, 5.0);
        assert_eq!(tr.sample_vec3(3.0).x, 20.0);
        assert_eq!(tr.sample_vec3(9.0).x, 30.0);
        tr.interpolation = Interpolation::Step;
        assert_eq!(tr.sample_vec3(1.99).x, 0.0);
        assert_eq!(tr.sample_vec3(2.0).x, 10.0);
        assert_eq!(tr.sample_vec3(3.9).x, 10.0);
    }

    #[test]
    fn linear_rotation_is_slerp() {
        let a = Quat::IDENTITY;
        let b = Quat::from_rotation_y(2.0);
        let tr = Track {
            times: vec![0.0, 1.0],
            values: vec![Vec4::from(a), Vec4::from(b)],
            interpolation: Interpolation::Linear,
        };
        // Component-wise lerp would give a different angle than 1.5 rad at s = 0.75.
        let q = tr.sample_quat(0.75);
        let (axis, angle) = q.to_axis_angle();
        assert!((angle - 1.5).abs() < 1e-5, "{angle}");
        assert!(axis.abs_diff_eq(Vec3::Y, 1e-5));
    }

    #[test]
    fn cubic_spline_hermite_with_scaled_tangents() {
        // Keys at t=0 (p=0, out-tangent 1) and t=2 (p=1, in-tangent 0). With dt = 2:
        // p(s) = (s³-2s²+s)·2 + (-2s³+3s²)·1. At t = 1 (s = 0.5): 0.25 + 0.5 = 0.75.
        let tr = Track {
            times: vec![0.0, 2.0],
            values: vec![v(9.0), v(0.0), v(1.0), v(0.0), v(1.0), v(9.0)],
            interpolation: Interpolation::CubicSpline,
        };
        assert!(tr.validate().is_ok());
        assert!((tr.sample_vec3(1.0).x - 0.75).abs() < 1e-6);
        assert_eq!(tr.sample_vec3(0.0).x, 0.0);
        assert_eq!(tr.sample_vec3(2.0).x, 1.0);
        assert_eq!(tr.sample_vec3(5.0).x, 1.0);
    }

    #[test]
    fn malformed_tracks_are_reported() {
        let bad_count = Track {
            times: vec![0.0, 1.0],
            values: vec![v(0.0), v(1.0)],
            interpolation: Interpolation::CubicSpline,
        };
        assert!(bad_count.validate().is_err());
        let unordered = Track {
            times: vec![1.0, 0.0],
            values: vec![v(0.0), v(1.0)],
            interpolation: Interpolation::Linear,
        };
        assert!(unordered.validate().is_err());
        let empty = Track {
            times: vec![],
            values: vec![],
            interpolation: Interpolation::Linear,
        };
        assert!(empty.validate().is_err());
    }
}
