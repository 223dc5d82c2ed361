//! The bounds every pose, skeleton and clip is held to where it enters the library, and the
//! NaN-safe arithmetic used where computed values meet a range.
//!
//! Values are checked where they are combined, not only where they are read: two finite
//! translations of 3e38 m each sum to infinity in forward kinematics, so a pose is accepted
//! only when each of its translations is small enough that any sum along a chain of
//! [`crate::skeleton::MAX_BONES`] bones stays finite (and far from where `f32` loses metres).

/// Largest magnitude of any component of a local translation (pose or rest), metres. Ten
/// kilometres: far beyond any capture volume, and 65,535 of them chained stay below 1e9 m,
/// where squares (distances) are still finite in `f32`.
pub const MAX_TRANSLATION_M: f32 = 1.0e4;

/// How far a rotation's quaternion may be from unit length and still be taken as a rotation
/// (then normalised); beyond this it is not one.
pub const ROTATION_LENGTH_RANGE: (f32, f32) = (0.5, 2.0);

/// A rotation this close to unit length is left as it is.
pub const UNIT_TOLERANCE: f32 = 1e-4;

/// Why a pose was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PoseFault {
    /// A translation or rotation holds NaN or infinity.
    NonFinite,
    /// A translation component beyond [`MAX_TRANSLATION_M`].
    TooFar,
    /// A quaternion too far from unit length (or zero) to be a rotation.
    NotARotation,
}

impl PoseFault {
    /// Every fault, in a fixed order (an index into this list fits an atomic counter).
    pub const ALL: [PoseFault; 3] = [
        PoseFault::NonFinite,
        PoseFault::TooFar,
        PoseFault::NotARotation,
    ];

    /// A short phrase for status reports.
    pub fn reason(self) -> &'static str {
        match self {
            PoseFault::NonFinite => "a value is not finite",
            PoseFault::TooFar => "a translation is beyond 10 km",
            PoseFault::NotARotation => "a quaternion is not a rotation",
        }
    }
}

impl std::fmt::Display for PoseFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.reason())
    }
}

/// A refused pose: why, and the first bone (index) that showed it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PoseRefusal {
    /// Why.
    pub fault: PoseFault,
    /// Index of the first bad bone.
    pub bone: usize,
}

/// Whether a translation is within bounds (finite and each component ≤ [`MAX_TRANSLATION_M`]).
#[inline]
pub fn translation_in_bounds(t: glam::Vec3) -> bool {
    // NaN fails every comparison, so it is out of bounds too.
    t.abs().cmple(glam::Vec3::splat(MAX_TRANSLATION_M)).all()
}

/// Bone samples (frames × bones) any reader or resampler may make from an input however small:
/// about 60 MB of poses.
pub const MIN_SAMPLE_BUDGET: u64 = 1 << 21;

/// How many times its input's own samples a derived clip (a resample, keyframes sampled at a
/// rate) may hold beyond [`MIN_SAMPLE_BUDGET`]: memory follows what the input holds, so a
/// few-kilobyte file cannot ask for gigabytes.
pub const MAX_SAMPLE_GROWTH: u64 = 8;

/// Most bone samples a clip derived from an input of `input_samples` may hold.
pub fn sample_budget(input_samples: u64) -> u64 {
    MIN_SAMPLE_BUDGET.max(input_samples.saturating_mul(MAX_SAMPLE_GROWTH))
}

/// The frame count `num_frames` (computed, possibly huge or not finite) as a `usize` when
/// `num_frames × num_bones` fits [`sample_budget`] of `input_samples`; else `None`.
pub fn frames_within_budget(
    num_frames: f64,
    num_bones: usize,
    input_samples: u64,
) -> Option<usize> {
    let budget = sample_budget(input_samples) as f64;
    let samples = num_frames * num_bones.max(1) as f64;
    (num_frames.is_finite() && num_frames >= 0.0 && samples <= budget)
        .then_some(num_frames as usize)
}

/// `x` limited to `lo..=hi` without ever panicking: unlike `f32::clamp` it accepts NaN bounds
/// and `lo > hi` (computed bounds can be either when their inputs are bad). A NaN `x` or bound
/// is ignored where the other side is a number (`f32::max`/`min` semantics); with `lo > hi`
/// the result is `hi`.
#[inline]
pub fn clamp_safe(x: f32, lo: f32, hi: f32) -> f32 {
    x.max(lo).min(hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamp_safe_never_panics() {
        assert_eq!(clamp_safe(5.0, 0.0, 1.0), 1.0);
        assert_eq!(clamp_safe(-5.0, 0.0, 1.0), 0.0);
        assert_eq!(clamp_safe(0.5, f32::NAN, 1.0), 0.5);
        assert_eq!(clamp_safe(2.0, 0.0, f32::NAN), 2.0);
        assert_eq!(clamp_safe(0.5, 1.0, 0.0), 0.0);
        assert!(clamp_safe(f32::NAN, 0.0, 1.0).is_finite());
    }
}
