//! Bones carried at a limb's end from beside it: an IK-style rig's foot hangs from the
//! armature root next to the legs, and its shin ends in a leaf, so turning the leg moves no
//! foot. Such a lone bone (the mapped bone driven by the source's child of the leaf's source,
//! see `build::Setup::detached_end`) is placed every frame where the leaf's end puts it, as if
//! it hung there: at its reference offset in the leaf's frame. Its rotation stays the
//! mapping's.

use glam::Vec3;

use crate::fk::WorldTransform;
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// One carried bone (a leaf: it carries nothing itself).
#[derive(Debug, Clone, Copy)]
pub(super) struct Carried {
    /// The bone placed.
    bone: BoneId,
    /// The limb's leaf it is carried by.
    by: BoneId,
    /// Where it sits in the leaf's frame (the target's reference posture).
    offset: Vec3,
}

impl Carried {
    /// The bone carried and the leaf carrying it.
    pub(super) fn pair(&self) -> (BoneId, BoneId) {
        (self.bone, self.by)
    }

    /// `bone` carried by leaf `by`, placed as the reference worlds `worlds` show them.
    pub(super) fn new(worlds: &[WorldTransform], bone: BoneId, by: BoneId) -> Self {
        let (b, l) = (worlds[bone.index()], worlds[by.index()]);
        Carried {
            bone,
            by,
            offset: l.rotation.inverse() * (b.translation - l.translation),
        }
    }
}

/// Places every bone of `carried` at its leaf's end (its translation under its own parent in
/// `out`), reading and updating the target's world transforms `worlds` (the skeleton of
/// `target`). Allocates nothing.
pub(super) fn carry(
    carried: &[Carried],
    target: &Skeleton,
    worlds: &mut [WorldTransform],
    out: &mut Pose,
) {
    for c in carried {
        let leaf = worlds[c.by.index()];
        place(
            c.bone,
            leaf.translation + leaf.rotation * c.offset,
            target,
            worlds,
            out,
        );
    }
}

/// Moves every bone of `carried` by `delta` (world space) after the root moved its leaves
/// by it (the feet's calibration onto the floor): a carried bone hangs from above the root,
/// so that move does not reach it through its parent. Its translation in `out` and its world
/// in `worlds` follow. Allocates nothing.
pub(super) fn shift(
    carried: &[Carried],
    target: &Skeleton,
    delta: Vec3,
    worlds: &mut [WorldTransform],
    out: &mut Pose,
) {
    if delta == Vec3::ZERO {
        return;
    }
    for c in carried {
        let position = worlds[c.bone.index()].translation + delta;
        place(c.bone, position, target, worlds, out);
    }
}

/// Puts `bone` at world `position`: its translation under its parent in `out`, and `worlds`.
fn place(
    bone: BoneId,
    position: Vec3,
    target: &Skeleton,
    worlds: &mut [WorldTransform],
    out: &mut Pose,
) {
    let parent = match target.parent(bone) {
        Some(p) => worlds[p.index()],
        None => WorldTransform::IDENTITY,
    };
    out.translations[bone.index()] = parent.rotation.inverse() * (position - parent.translation);
    worlds[bone.index()].translation = position;
}
