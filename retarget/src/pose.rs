//! `Pose` and `Frame`: what a source produces each frame.

use glam::{Quat, Vec3};

use crate::error::RetargetError;
use crate::skeleton::{BoneId, Skeleton};

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

    /// Translation of the first root bone (bone 0).
    #[inline]
    pub fn root_translation(&self) -> Vec3 {
        self.translations[0]
    }

    /// Sets the translation of bone 0.
    #[inline]
    pub fn set_root_translation(&mut self, t: Vec3) {
        self.translations[0] = t;
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

    /// Copies `other` into `self` without allocating (sizes must match).
    #[inline]
    pub fn copy_from(&mut self, other: &Pose) {
        self.rotations.copy_from_slice(&other.rotations);
        self.translations.copy_from_slice(&other.translations);
    }

    /// Interpolates between `a` and `b` (`t` in 0..=1) into `self`: shortest-arc slerp for
    /// rotations, lerp for translations. Allocates nothing.
    pub fn interpolate_into(&mut self, a: &Pose, b: &Pose, t: f32) {
        debug_assert_eq!(a.num_bones(), self.num_bones());
        debug_assert_eq!(b.num_bones(), self.num_bones());
        for i in 0..self.rotations.len() {
            let qa = a.rotations[i];
            let mut qb = b.rotations[i];
            if qa.dot(qb) < 0.0 {
                qb = -qb;
            }
            self.rotations[i] = qa.slerp(qb, t).normalize();
            self.translations[i] = a.translations[i].lerp(b.translations[i], t);
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
