//! # rigcast-retarget — the pure core of rigcast
//!
//! Everything here is synchronous, does no IO and, in per-frame calls, allocates nothing.
//!
//! ```text
//!   RawSkeleton ──build/validate──▶ Skeleton (immutable, depth-first, parent[i] < i)
//!                                      │
//!   Pose (local rotations + translations, one per bone, struct of arrays)
//!                                      │ forward_kinematics(&skeleton, &pose, &mut world)
//!                                      ▼
//!                               [WorldTransform] (caller-owned buffer)
//!
//!   Mapping::apply (retarget) ─▶ target Pose ─▶ footplant::FootLock (planted feet pinned)
//!   graft: upper body of one clip spliced onto another's legs, in step with its footplants
//!
//!   Clip = Skeleton + Vec<Pose> + frame time      (what files decode into)
//!   Frame = { seq, capture_nanos, source_id, pose } (what moves through channels)
//! ```
//!
//! Conventions: right-handed, +Y up, metres, seconds, quaternions. Local rotations in a [`Pose`]
//! are the bone's full local rotation (not a delta from rest), so the rest pose is simply
//! [`Skeleton::rest_pose`]. Conversions to other conventions (BVH Euler channels, Unity, Blender)
//! happen at the edges, in one function each.
#![warn(missing_docs)]

pub mod analysis;
pub mod bounds;
pub mod clip;
#[cfg(any(test, feature = "corpus"))]
pub mod corpus;
pub mod error;
pub mod fk;
pub mod footplant;
pub mod graft;
pub mod graph;
pub mod mapping;
pub mod pose;
pub mod procedural;
pub mod retarget;
pub mod rotation;
pub mod skeleton;

pub use clip::Clip;
pub use error::RetargetError;
pub use fk::{forward_kinematics, world_transforms, WorldTransform};
pub use pose::{Frame, Pose};
pub use retarget::{
    Follow, FootContact, Mapping, RetargetContext, RetargetOptions, RetargetPlan, RootMotion,
};
pub use rotation::RotationOrder;
pub use skeleton::{BoneId, RawBone, RawSkeleton, Skeleton, Transform};

/// Approximate-equality helpers shared by unit tests across the crate (and usable by other
/// crates' tests).
pub mod approx {
    use glam::{Quat, Vec3};

    /// Angle in radians between two rotations, treating `q` and `-q` as equal.
    pub fn quat_angle(a: Quat, b: Quat) -> f32 {
        let d = a.dot(b).abs().min(1.0);
        2.0 * d.acos()
    }

    /// True when the rotations differ by less than `tol_rad`.
    pub fn quat_close(a: Quat, b: Quat, tol_rad: f32) -> bool {
        quat_angle(a, b) <= tol_rad
    }

    /// [`quat_close`] measured from the sine of the half angle, accurate for tiny angles (the
    /// cosine of [`quat_angle`] is not); q and -q give the same sine, so no sign handling is
    /// needed.
    pub fn quat_close_precise(a: Quat, b: Quat, tol_rad: f32) -> bool {
        let d = a.conjugate() * b;
        2.0 * d.xyz().length().min(1.0).asin() <= tol_rad
    }

    /// True when the points are within `tol` (same unit as the points).
    pub fn vec_close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).length() <= tol
    }
}
