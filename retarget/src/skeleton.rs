//! `Skeleton`: an immutable, validated bone hierarchy with rest transforms.
//!
//! Built from an editable [`RawSkeleton`] (any bone order) by [`Skeleton::build`], which
//! validates it and reorders bones depth-first so that `parent[i] < i` holds for every bone.
//! That ordering lets forward kinematics run in a single forward pass.

use std::collections::HashMap;

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::RetargetError;

/// Index of a bone inside one [`Skeleton`]. Names are resolved to ids once; per-frame code uses
/// ids only.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct BoneId(pub u16);

impl BoneId {
    /// The id as a slice index.
    #[inline]
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// A rigid local transform (no scale: readers bake uniform scale into translations).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Offset from the parent's origin, in the parent's frame, metres.
    pub translation: Vec3,
    /// Rotation relative to the parent.
    pub rotation: Quat,
}

impl Transform {
    /// The identity transform.
    pub const IDENTITY: Transform = Transform {
        translation: Vec3::ZERO,
        rotation: Quat::IDENTITY,
    };

    /// A transform with the given translation and no rotation.
    pub fn from_translation(translation: Vec3) -> Self {
        Transform {
            translation,
            rotation: Quat::IDENTITY,
        }
    }
}

/// One bone of a [`RawSkeleton`].
#[derive(Debug, Clone, PartialEq)]
pub struct RawBone {
    /// Unique name.
    pub name: String,
    /// Index of the parent in the raw bone list, `None` for a root.
    pub parent: Option<usize>,
    /// Rest (bind) local transform.
    pub rest: Transform,
}

/// Editable skeleton description, in any bone order. Turn it into a [`Skeleton`] with
/// [`Skeleton::build`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RawSkeleton {
    /// The bones.
    pub bones: Vec<RawBone>,
}

impl RawSkeleton {
    /// Appends a bone and returns its raw index (convenient for building trees in code).
    pub fn add(
        &mut self,
        name: impl Into<String>,
        parent: Option<usize>,
        rest: Transform,
    ) -> usize {
        self.bones.push(RawBone {
            name: name.into(),
            parent,
            rest,
        });
        self.bones.len() - 1
    }
}

/// An immutable, validated skeleton. Bones are in depth-first order (`parent[i] < i`), names are
/// unique, rest transforms are finite.
#[derive(Debug, Clone)]
pub struct Skeleton {
    names: Vec<String>,
    parents: Vec<Option<BoneId>>,
    rest: Vec<Transform>,
    children: Vec<Vec<BoneId>>,
    by_name: HashMap<String, BoneId>,
    fingerprint: u64,
}

impl PartialEq for Skeleton {
    fn eq(&self, other: &Self) -> bool {
        self.names == other.names && self.parents == other.parents && self.rest == other.rest
    }
}

/// Checks one raw bone (`i` of `n`): a finite rest within bounds, a parent that exists.
fn check_bone(i: usize, b: &RawBone, n: usize) -> Result<(), RetargetError> {
    let finite = b.rest.translation.is_finite() && b.rest.rotation.is_finite();
    if !finite {
        return Err(RetargetError::NonFiniteRest {
            bone: i,
            name: b.name.clone(),
        });
    }
    if !crate::bounds::translation_in_bounds(b.rest.translation) {
        return Err(RetargetError::RestOutOfRange {
            bone: i,
            name: b.name.clone(),
        });
    }
    match b.parent {
        Some(p) if p >= n => Err(RetargetError::ParentOutOfRange {
            bone: i,
            name: b.name.clone(),
            parent: p,
            num_bones: n,
        }),
        _ => Ok(()),
    }
}

/// The raw bones' depth-first order from the roots (children in their given order), without
/// recursion; a bone not reached sits on a parent cycle, which is an error.
fn depth_first(
    raw: &RawSkeleton,
    roots: &[usize],
    children: &[Vec<usize>],
) -> Result<Vec<usize>, RetargetError> {
    let n = raw.bones.len();
    let mut order = Vec::with_capacity(n);
    let mut stack: Vec<usize> = roots.iter().rev().copied().collect();
    while let Some(i) = stack.pop() {
        order.push(i);
        stack.extend(children[i].iter().rev().copied());
    }
    if order.len() != n {
        let mut reached = vec![false; n];
        for &i in &order {
            reached[i] = true;
        }
        let bone = reached.iter().position(|r| !r).unwrap_or(0);
        return Err(RetargetError::ParentCycle {
            bone,
            name: raw.bones[bone].name.clone(),
        });
    }
    Ok(order)
}

/// Largest supported bone count (ids are `u16`; wire formats use `u32` counts).
pub const MAX_BONES: usize = u16::MAX as usize;

impl Skeleton {
    /// Validates `raw` and reorders its bones depth-first (children keep their relative order).
    /// Returns the skeleton; use [`Skeleton::bone`] to find bones by name afterwards.
    pub fn build(raw: &RawSkeleton) -> Result<Skeleton, RetargetError> {
        let n = raw.bones.len();
        if n == 0 {
            return Err(RetargetError::EmptySkeleton);
        }
        if n > MAX_BONES {
            return Err(RetargetError::TooManyBones {
                num_bones: n,
                max: MAX_BONES,
            });
        }
        let mut seen: HashMap<&str, usize> = HashMap::with_capacity(n);
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut roots = Vec::new();
        for (i, b) in raw.bones.iter().enumerate() {
            if let Some(first) = seen.insert(b.name.as_str(), i) {
                return Err(RetargetError::DuplicateBoneName {
                    name: b.name.clone(),
                    first,
                    second: i,
                });
            }
            check_bone(i, b, n)?;
            match b.parent {
                Some(p) => children[p].push(i),
                None => roots.push(i),
            }
        }
        let order = depth_first(raw, &roots, &children)?;
        let mut new_index = vec![0usize; n];
        for (new, &old) in order.iter().enumerate() {
            new_index[old] = new;
        }
        let names: Vec<String> = order.iter().map(|&o| raw.bones[o].name.clone()).collect();
        let parents: Vec<Option<BoneId>> = order
            .iter()
            .map(|&o| raw.bones[o].parent.map(|p| BoneId(new_index[p] as u16)))
            .collect();
        let rest: Vec<Transform> = order
            .iter()
            .map(|&o| {
                let r = raw.bones[o].rest;
                Transform {
                    translation: r.translation,
                    rotation: r.rotation.normalize(),
                }
            })
            .collect();
        Ok(Self::from_parts(names, parents, rest))
    }

    fn from_parts(names: Vec<String>, parents: Vec<Option<BoneId>>, rest: Vec<Transform>) -> Self {
        let n = names.len();
        let mut children = vec![Vec::new(); n];
        for (i, p) in parents.iter().enumerate() {
            if let Some(p) = p {
                children[p.index()].push(BoneId(i as u16));
            }
        }
        let by_name = names
            .iter()
            .enumerate()
            .map(|(i, s)| (s.clone(), BoneId(i as u16)))
            .collect();
        let fingerprint = fingerprint_of(&names, &parents, &rest);
        Skeleton {
            names,
            parents,
            rest,
            children,
            by_name,
            fingerprint,
        }
    }

    /// Number of bones.
    #[inline]
    pub fn num_bones(&self) -> usize {
        self.names.len()
    }

    /// Bone names, indexed by [`BoneId`].
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Name of one bone.
    pub fn name(&self, bone: BoneId) -> &str {
        &self.names[bone.index()]
    }

    /// Parent links, indexed by [`BoneId`]; `None` for roots.
    pub fn parents(&self) -> &[Option<BoneId>] {
        &self.parents
    }

    /// Parent of one bone.
    pub fn parent(&self, bone: BoneId) -> Option<BoneId> {
        self.parents[bone.index()]
    }

    /// Whether `bone` hangs (at any depth) below `ancestor`; a bone is not below itself.
    /// Parents come before their children (checked at construction), so the walk ends.
    pub fn is_below(&self, bone: BoneId, ancestor: BoneId) -> bool {
        let mut b = self.parent(bone);
        while let Some(p) = b {
            if p == ancestor {
                return true;
            }
            b = self.parent(p);
        }
        false
    }

    /// Children of one bone, in their original order.
    pub fn children(&self, bone: BoneId) -> &[BoneId] {
        &self.children[bone.index()]
    }

    /// Rest local transforms, indexed by [`BoneId`].
    pub fn rest(&self) -> &[Transform] {
        &self.rest
    }

    /// Finds a bone by exact name.
    pub fn bone(&self, name: &str) -> Option<BoneId> {
        self.by_name.get(name).copied()
    }

    /// All bone ids in depth-first order.
    pub fn bone_ids(&self) -> impl Iterator<Item = BoneId> + '_ {
        (0..self.num_bones()).map(|i| BoneId(i as u16))
    }

    /// Root bones (bones without a parent).
    pub fn roots(&self) -> impl Iterator<Item = BoneId> + '_ {
        self.bone_ids()
            .filter(|b| self.parents[b.index()].is_none())
    }

    /// Number of ancestors of a bone (roots have depth 0).
    pub fn depth(&self, bone: BoneId) -> usize {
        let mut d = 0;
        let mut b = bone;
        while let Some(p) = self.parents[b.index()] {
            d += 1;
            b = p;
        }
        d
    }

    /// Stable 64-bit fingerprint of topology, names and rest transforms (rest values quantised to
    /// 1e-5 so that float noise from a write→read round trip does not change it). Stable across
    /// runs, platforms and Rust versions: it is used as an on-disk cache key.
    pub fn fingerprint(&self) -> u64 {
        self.fingerprint
    }

    /// The fingerprint as 16 lowercase hex digits.
    pub fn fingerprint_hex(&self) -> String {
        format!("{:016x}", self.fingerprint)
    }

    /// A copy with every bone renamed by `rename(id, old_name)`. Fails if names collide.
    pub fn renamed(
        &self,
        mut rename: impl FnMut(BoneId, &str) -> String,
    ) -> Result<Skeleton, RetargetError> {
        let raw = RawSkeleton {
            bones: self
                .bone_ids()
                .map(|b| RawBone {
                    name: rename(b, self.name(b)),
                    parent: self.parent(b).map(BoneId::index),
                    rest: self.rest[b.index()],
                })
                .collect(),
        };
        Skeleton::build(&raw)
    }

    /// The editable form of this skeleton (bones in the same order).
    pub fn to_raw(&self) -> RawSkeleton {
        RawSkeleton {
            bones: self
                .bone_ids()
                .map(|b| RawBone {
                    name: self.name(b).to_string(),
                    parent: self.parent(b).map(BoneId::index),
                    rest: self.rest[b.index()],
                })
                .collect(),
        }
    }
}

/// FNV-1a, 64-bit: tiny, dependency-free and fixed forever (unlike `DefaultHasher`).
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn float(&mut self, v: f32) {
        // Quantise, and fold -0 into 0, so round-tripped values hash alike.
        let q = (v as f64 * 1e5).round() as i64;
        self.bytes(&q.to_le_bytes());
    }
}

fn fingerprint_of(names: &[String], parents: &[Option<BoneId>], rest: &[Transform]) -> u64 {
    let mut h = Fnv::new();
    h.bytes(&(names.len() as u64).to_le_bytes());
    for i in 0..names.len() {
        h.bytes(&(names[i].len() as u64).to_le_bytes());
        h.bytes(names[i].as_bytes());
        let p = parents[i].map(|p| p.0 as u32).unwrap_or(u32::MAX);
        h.bytes(&p.to_le_bytes());
        let t = rest[i].translation;
        // q and -q are the same rotation: hash a canonical sign.
        let mut q = rest[i].rotation;
        if q.w < 0.0 {
            q = -q;
        }
        for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
            h.float(v);
        }
    }
    h.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain() -> RawSkeleton {
        let mut raw = RawSkeleton::default();
        // Deliberately out of order: child listed before parent.
        raw.bones.push(RawBone {
            name: "b".into(),
            parent: Some(1),
            rest: Transform::from_translation(Vec3::Y),
        });
        raw.bones.push(RawBone {
            name: "a".into(),
            parent: None,
            rest: Transform::IDENTITY,
        });
        raw.bones.push(RawBone {
            name: "c".into(),
            parent: Some(0),
            rest: Transform::from_translation(Vec3::Y),
        });
        raw
    }

    #[test]
    fn build_reorders_depth_first() {
        let s = Skeleton::build(&chain()).expect("valid");
        assert_eq!(s.names(), &["a", "b", "c"]);
        for (i, p) in s.parents().iter().enumerate() {
            if let Some(p) = p {
                assert!(p.index() < i);
            }
        }
        assert_eq!(s.bone("c"), Some(BoneId(2)));
        assert_eq!(s.depth(BoneId(2)), 2);
        assert_eq!(s.children(BoneId(0)), &[BoneId(1)]);
    }

    #[test]
    fn is_below_follows_parents_strictly() {
        let s = Skeleton::build(&chain()).expect("valid");
        let [a, b, c] = ["a", "b", "c"].map(|n| s.bone(n).unwrap());
        assert!(s.is_below(c, a) && s.is_below(c, b) && s.is_below(b, a));
        assert!(!s.is_below(a, c) && !s.is_below(b, c) && !s.is_below(a, a));
    }

    #[test]
    fn rejects_bad_input() {
        assert_eq!(
            Skeleton::build(&RawSkeleton::default()),
            Err(RetargetError::EmptySkeleton)
        );
        let mut dup = chain();
        dup.bones[2].name = "a".into();
        assert!(matches!(
            Skeleton::build(&dup),
            Err(RetargetError::DuplicateBoneName { .. })
        ));
        let mut out = chain();
        out.bones[2].parent = Some(9);
        assert!(matches!(
            Skeleton::build(&out),
            Err(RetargetError::ParentOutOfRange { .. })
        ));
        let mut cyc = chain();
        cyc.bones[1].parent = Some(2);
        assert!(matches!(
            Skeleton::build(&cyc),
            Err(RetargetError::ParentCycle { .. })
        ));
        let mut nan = chain();
        nan.bones[0].rest.translation.x = f32::NAN;
        assert!(matches!(
            Skeleton::build(&nan),
            Err(RetargetError::NonFiniteRest { .. })
        ));
    }

    #[test]
    fn fingerprint_is_stable_and_sensitive() {
        let a = Skeleton::build(&chain()).expect("valid");
        let again = Skeleton::build(&chain()).expect("valid");
        assert_eq!(a.fingerprint(), again.fingerprint());
        let mut moved = chain();
        moved.bones[2].rest.translation.y = 1.1;
        assert_ne!(
            a.fingerprint(),
            Skeleton::build(&moved).expect("valid").fingerprint()
        );
        let mut renamed = chain();
        renamed.bones[2].name = "z".into();
        assert_ne!(
            a.fingerprint(),
            Skeleton::build(&renamed).expect("valid").fingerprint()
        );
        let mut noisy = chain();
        noisy.bones[2].rest.translation.y = 1.0 + 1e-7;
        assert_eq!(
            a.fingerprint(),
            Skeleton::build(&noisy).expect("valid").fingerprint()
        );
        assert_eq!(a.fingerprint_hex().len(), 16);
    }
}
