//! `Pose` and `Frame`: what a source produces each frame.

use glam::{Quat, Vec3};

use crate::bounds::{PoseFault, PoseRefusal};
use crate::error::RetargetError;
use crate::skeleton::{BoneId, Skeleton};

// Here rather than in skeleton.rs, so that the skeleton (the lower module) does not know poses.
impl Skeleton {
    /// The pose in which every bone sits at its rest transform.
    pub fn rest_pose(&self) -> Pose {
        Pose::from_rest(self)
    }
}

/// Local transforms of every bone of one skeleton, as a struct of arrays.
///
/// `rotations[i]` is bone `i`'s full local rotation relative to its parent (not a delta from
/// rest). `translations[i]` is its local offset; for every bone but the root(s) this normally
/// stays at the rest offset, but files that animate non-root translations (some BVH exports do)
/// keep that data exactly. The root translation is `translations[0]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    /// Local rotation per bone.
    pub rotations: Vec<Quat>,
    /// Local translation per bone, metres.
    pub translations: Vec<Vec3>,
}

impl Pose {
    /// The rest pose of `skeleton`.
    pub fn from_rest(skeleton: &Skeleton) -> Pose {
        Pose {
            rotations: skeleton.rest().iter().map(|t| t.rotation).collect(),
            translations: skeleton.rest().iter().map(|t| t.translation).collect(),
        }
    }

    /// Number of bones.
    #[inline]
    pub fn num_bones(&self) -> usize {
        self.rotations.len()
    }

    /// Translation of the first root bone (bone 0); zero for an empty pose (no skeleton has
    /// one, but `Pose` is plain data anyone can build).
    #[inline]
    pub fn root_translation(&self) -> Vec3 {
        self.translations.first().copied().unwrap_or(Vec3::ZERO)
    }

    /// Sets the translation of bone 0 (nothing for an empty pose).
    #[inline]
    pub fn set_root_translation(&mut self, t: Vec3) {
        if let Some(root) = self.translations.first_mut() {
            *root = t;
        }
    }

    /// Local rotation of one bone.
    #[inline]
    pub fn rotation(&self, bone: BoneId) -> Quat {
        self.rotations[bone.index()]
    }

    /// Checks that the pose fits `skeleton`.
    pub fn check(&self, skeleton: &Skeleton) -> Result<(), RetargetError> {
        let n = skeleton.num_bones();
        if self.rotations.len() != n || self.translations.len() != n {
            return Err(RetargetError::PoseSizeMismatch {
                expected: n,
                got: self.rotations.len().min(self.translations.len()),
            });
        }
        Ok(())
    }

    /// Checks a whole pose and repairs what can be repaired in place: rotations close to unit
    /// length are normalised. Returns how many rotations were normalised, or why the pose cannot
    /// be used (then it may be partly normalised and must be dropped). Allocates nothing.
    pub fn check_values(&mut self) -> Result<usize, PoseRefusal> {
        let pose = self;
        for (bone, t) in pose.translations.iter().enumerate() {
            if !t.is_finite() {
                return Err(PoseRefusal {
                    fault: PoseFault::NonFinite,
                    bone,
                });
            }
            if !crate::bounds::translation_in_bounds(*t) {
                return Err(PoseRefusal {
                    fault: PoseFault::TooFar,
                    bone,
                });
            }
        }
        let mut normalised = 0;
        for (bone, q) in pose.rotations.iter_mut().enumerate() {
            if !q.is_finite() {
                return Err(PoseRefusal {
                    fault: PoseFault::NonFinite,
                    bone,
                });
            }
            let len = q.length();
            if !(crate::bounds::ROTATION_LENGTH_RANGE.0..=crate::bounds::ROTATION_LENGTH_RANGE.1)
                .contains(&len)
            {
                return Err(PoseRefusal {
                    fault: PoseFault::NotARotation,
                    bone,
                });
            }
            if (len - 1.0).abs() > crate::bounds::UNIT_TOLERANCE {
                *q /= len;
                normalised += 1;
            }
        }
        Ok(normalised)
    }

    /// Copies `other` into `self` without allocating. Sizes must match (a caller bug otherwise:
    /// debug builds assert, release builds copy the bones both have rather than panic).
    #[inline]
    pub fn copy_from(&mut self, other: &Pose) {
        debug_assert_eq!(other.num_bones(), self.num_bones());
        for (d, s) in self.rotations.iter_mut().zip(&other.rotations) {
            *d = *s;
        }
        for (d, s) in self.translations.iter_mut().zip(&other.translations) {
            *d = *s;
        }
    }

    /// Interpolates between `a` and `b` (`t` in 0..=1) into `self`: shortest-arc slerp for
    /// rotations, lerp for translations. Allocates nothing. Sizes must match, as for
    /// [`Pose::copy_from`].
    pub fn interpolate_into(&mut self, a: &Pose, b: &Pose, t: f32) {
        debug_assert_eq!(a.num_bones(), self.num_bones());
        debug_assert_eq!(b.num_bones(), self.num_bones());
        let rotations = a.rotations.iter().zip(&b.rotations);
        for (out, (&qa, &qb)) in self.rotations.iter_mut().zip(rotations) {
            // q and -q are the same rotation: slerp along the shorter arc.
            let qb = if qa.dot(qb) < 0.0 { -qb } else { qb };
            *out = qa.slerp(qb, t).normalize();
        }
        let translations = a.translations.iter().zip(&b.translations);
        for (out, (&ta, &tb)) in self.translations.iter_mut().zip(translations) {
            *out = ta.lerp(tb, t);
        }
    }
}

/// A pose with its provenance, as it moves through channels from a source to the engine tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Per-source sequence number, increasing by one per produced frame.
    pub seq: u64,
    /// When the pose was captured, nanoseconds since the Unix epoch.
    pub capture_nanos: u64,
    /// Which source produced it.
    pub source_id: u32,
    /// The pose, on the source's skeleton.
    pub pose: Pose,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::{quat_close, vec_close};

    fn pose(r: Quat, t: Vec3) -> Pose {
        Pose {
            rotations: vec![Quat::IDENTITY, r],
            translations: vec![Vec3::ZERO, t],
        }
    }

    #[test]
    fn interpolation_takes_the_short_arc_and_lerps_translations() {
        let a = pose(Quat::IDENTITY, Vec3::ZERO);
        // 1.0 rad about Y, stored with the opposite sign: the midpoint is still 0.5 rad, not
        // the long way round.
        let b = pose(-Quat::from_rotation_y(1.0), Vec3::new(2.0, 0.0, -4.0));
        let mut out = a.clone();
        out.interpolate_into(&a, &b, 0.5);
        assert!(quat_close(
            out.rotations[1],
            Quat::from_rotation_y(0.5),
            1e-5
        ));
        assert!(vec_close(
            out.translations[1],
            Vec3::new(1.0, 0.0, -2.0),
            1e-6
        ));
        out.copy_from(&b);
        assert_eq!(out, b);
    }

    #[test]
    fn root_translation_of_an_empty_pose_is_zero_not_a_panic() {
        let mut p = Pose {
            rotations: Vec::new(),
            translations: Vec::new(),
        };
        p.set_root_translation(Vec3::X);
        assert_eq!(p.root_translation(), Vec3::ZERO);
        let mut q = pose(Quat::IDENTITY, Vec3::Y);
        q.set_root_translation(Vec3::X);
        assert_eq!(q.root_translation(), Vec3::X);
    }
    fn two_bones(t: Vec3, q: Quat) -> Pose {
        Pose {
            rotations: vec![Quat::IDENTITY, q],
            translations: vec![Vec3::ZERO, t],
        }
    }

    #[test]
    fn refuses_values_that_overflow_when_combined() {
        // Each finite; their sum along the chain is not.
        let mut p = two_bones(Vec3::splat(3e38), Quat::IDENTITY);
        let r = p.check_values().unwrap_err();
        assert_eq!(r.fault, PoseFault::TooFar);
        assert_eq!(r.bone, 1);
        let mut p = two_bones(Vec3::new(0.0, f32::NAN, 0.0), Quat::IDENTITY);
        assert_eq!(p.check_values().unwrap_err().fault, PoseFault::NonFinite);
        let mut p = two_bones(Vec3::ZERO, Quat::from_xyzw(0.0, 0.0, 0.0, 0.0));
        assert_eq!(p.check_values().unwrap_err().fault, PoseFault::NotARotation);
        let mut p = two_bones(Vec3::ZERO, Quat::from_xyzw(f32::INFINITY, 0.0, 0.0, 1.0));
        assert_eq!(p.check_values().unwrap_err().fault, PoseFault::NonFinite);
    }

    #[test]
    fn normalises_nearly_unit_rotations_and_keeps_good_poses() {
        let mut p = two_bones(
            Vec3::new(9_999.0, -1.0, 0.5),
            Quat::from_xyzw(0.0, 0.0, 0.0, 1.5),
        );
        assert_eq!(p.check_values(), Ok(1));
        assert!((p.rotations[1].length() - 1.0).abs() < 1e-6);
        assert_eq!(p.check_values(), Ok(0));
    }
}
