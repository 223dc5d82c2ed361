//! Perturbations of real labelled rigs, for judging how the mapping generalises with real data
//! only: the changes unseen rig families bring (a backpack chain and ribbons, twist bones,
//! zero-length helpers, scapula bones, cartoon proportions, no animation, a rig facing the
//! other way) made on the real rigs, whose labels still say what every original bone is.
//!
//! Every change keeps the world motion of the original bones: an added bone has the identity
//! rotation in every frame, and a bone inserted above another splits that bone's offset.
#![allow(dead_code)]

use glam::{Quat, Vec3};
use rigcast_retarget::{Clip, Pose, RawBone, RawSkeleton, Skeleton, Transform};

/// A clip as editable raw bones and per-frame local transforms (indexed like `raw.bones`).
pub struct Editable {
    pub raw: RawSkeleton,
    rotations: Vec<Vec<Quat>>,
    translations: Vec<Vec<Vec3>>,
    name: String,
    frame_time: f64,
}

impl Editable {
    pub fn from_clip(clip: &Clip) -> Self {
        Editable {
            raw: clip.skeleton.to_raw(),
            rotations: clip.poses.iter().map(|p| p.rotations.clone()).collect(),
            translations: clip.poses.iter().map(|p| p.translations.clone()).collect(),
            name: clip.name.clone(),
            frame_time: clip.frame_time_secs,
        }
    }

    pub fn index(&self, name: &str) -> Option<usize> {
        self.raw.bones.iter().position(|b| b.name == name)
    }

    /// Bone `b`'s world rotation in frame `frame` (the rest when `None` or out of range).
    pub fn world_rotation(&self, mut b: usize, frame: Option<usize>) -> Quat {
        let mut q = Quat::IDENTITY;
        // Walks up the parents; a cycle cannot exist (the raw came from a built skeleton).
        for _ in 0..self.raw.bones.len() {
            let local = match frame.and_then(|f| self.rotations.get(f)) {
                Some(r) => r[b],
                None => self.raw.bones[b].rest.rotation,
            };
            q = local * q;
            match self.raw.bones[b].parent {
                Some(p) => b = p,
                None => break,
            }
        }
        q
    }

    fn push(
        &mut self,
        name: String,
        parent: Option<usize>,
        offset: Vec3,
        per_frame: &[Vec3],
    ) -> usize {
        self.raw.bones.push(RawBone {
            name,
            parent,
            rest: Transform::from_translation(offset),
        });
        for (r, t) in self.rotations.iter_mut().zip(&mut self.translations) {
            r.push(Quat::IDENTITY);
            t.push(offset);
        }
        for (t, &v) in self.translations.iter_mut().zip(per_frame) {
            *t.last_mut().expect("pushed") = v;
        }
        self.raw.bones.len() - 1
    }

    /// A new leaf (or chain start) under `parent` at `offset` in the parent's local frame.
    pub fn add_child(&mut self, parent: usize, name: &str, offset: Vec3) -> usize {
        self.push(name.to_string(), Some(parent), offset, &[])
    }

    /// A new bone under `parent` whose offset is `world` (a direction and length in the
    /// skeleton's space) in the posture of frame `frame`.
    pub fn add_world(
        &mut self,
        parent: usize,
        name: &str,
        world: Vec3,
        frame: Option<usize>,
    ) -> usize {
        let local = self.world_rotation(parent, frame).inverse() * world;
        self.add_child(parent, name, local)
    }

    /// A new bone between `bone` and its parent, at `frac` of `bone`'s offset (0: on the
    /// parent's joint, a zero-length helper; 1: on `bone`'s joint, making `bone` zero-length).
    pub fn insert_above(&mut self, bone: usize, name: &str, frac: f32) -> usize {
        let parent = self.raw.bones[bone].parent;
        let rest = self.raw.bones[bone].rest.translation;
        let per_frame: Vec<Vec3> = self.translations.iter().map(|t| t[bone] * frac).collect();
        let new = self.push(name.to_string(), parent, rest * frac, &per_frame);
        self.raw.bones[bone].parent = Some(new);
        self.raw.bones[bone].rest.translation = rest * (1.0 - frac);
        for t in &mut self.translations {
            t[bone] *= 1.0 - frac;
        }
        new
    }

    /// Scales `bone`'s offset from its parent (rest and every frame) by `k`.
    pub fn scale_offset(&mut self, bone: usize, k: f32) {
        self.raw.bones[bone].rest.translation *= k;
        for t in &mut self.translations {
            t[bone] *= k;
        }
    }

    /// Moves `bone` (rest and every frame) by `world`, a displacement in the skeleton's space
    /// as its parent is turned in frame `frame`.
    pub fn shift(&mut self, bone: usize, world: Vec3, frame: Option<usize>) {
        let local = match self.raw.bones[bone].parent {
            Some(p) => self.world_rotation(p, frame).inverse() * world,
            None => world,
        };
        self.raw.bones[bone].rest.translation += local;
        for t in &mut self.translations {
            t[bone] += local;
        }
    }

    /// Every bone below `bone` (not itself), by walking the parents (no recursion).
    pub fn below(&self, bone: usize) -> Vec<usize> {
        (0..self.raw.bones.len())
            .filter(|&b| {
                let mut c = self.raw.bones[b].parent;
                for _ in 0..self.raw.bones.len() {
                    match c {
                        Some(p) if p == bone => return true,
                        Some(p) => c = self.raw.bones[p].parent,
                        None => return false,
                    }
                }
                false
            })
            .collect()
    }

    /// The pose of frame `frame` made the rest, and no animation: a static character.
    pub fn make_static(&mut self, frame: Option<usize>) {
        if let Some(f) = frame.filter(|&f| f < self.rotations.len()) {
            for (b, bone) in self.raw.bones.iter_mut().enumerate() {
                bone.rest.rotation = self.rotations[f][b];
                if bone.parent.is_some() {
                    bone.rest.translation = self.translations[f][b];
                }
            }
        }
        self.rotations.clear();
        self.translations.clear();
    }

    /// The whole rig turned by `g` (its roots' rest and every frame).
    pub fn turn(&mut self, g: Quat) {
        for (b, bone) in self.raw.bones.iter_mut().enumerate() {
            if bone.parent.is_some() {
                continue;
            }
            bone.rest.translation = g * bone.rest.translation;
            bone.rest.rotation = g * bone.rest.rotation;
            for (r, t) in self.rotations.iter_mut().zip(&mut self.translations) {
                r[b] = g * r[b];
                t[b] = g * t[b];
            }
        }
    }

    pub fn to_clip(&self) -> Clip {
        let skel = Skeleton::build(&self.raw).expect("perturbed skeleton");
        let raw_of: Vec<usize> = skel
            .names()
            .iter()
            .map(|n| self.index(n).expect("bone"))
            .collect();
        let poses = self
            .rotations
            .iter()
            .zip(&self.translations)
            .map(|(r, t)| Pose {
                rotations: raw_of.iter().map(|&i| r[i]).collect(),
                translations: raw_of.iter().map(|&i| t[i]).collect(),
            })
            .collect();
        Clip::new(
            self.name.clone(),
            std::sync::Arc::new(skel),
            poses,
            self.frame_time,
        )
        .expect("perturbed clip")
    }
}
