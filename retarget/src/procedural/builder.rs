//! A tiny world-space skeleton builder (built-in characters, fixtures): bones are placed by world position (and
//! optionally a world rotation), locals are derived at the end.

use glam::{Quat, Vec3};

use crate::skeleton::{RawSkeleton, Skeleton, Transform};

/// Builds a skeleton from world positions; every bone carries a ground-truth label.
#[derive(Debug, Clone, Default)]
pub struct Builder {
    pub(crate) names: Vec<String>,
    pub(crate) parents: Vec<Option<usize>>,
    pub(crate) world_pos: Vec<Vec3>,
    pub(crate) world_rot: Vec<Quat>,
    pub(crate) labels: Vec<String>,
}

impl Builder {
    /// Adds a bone at a world position, identity world rotation. Returns its index.
    pub fn add(&mut self, name: &str, parent: Option<usize>, pos: Vec3, label: &str) -> usize {
        self.names.push(name.to_string());
        self.parents.push(parent);
        self.world_pos.push(pos);
        self.world_rot.push(Quat::IDENTITY);
        self.labels.push(label.to_string());
        self.names.len() - 1
    }

    /// Index of a bone by name.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    fn descendants(&self, root: usize) -> Vec<usize> {
        let mut out = vec![root];
        let mut i = 0;
        while i < out.len() {
            let b = out[i];
            for (c, p) in self.parents.iter().enumerate() {
                if *p == Some(b) {
                    out.push(c);
                }
            }
            i += 1;
        }
        out
    }

    /// Rotates a subtree about its root joint (A-pose: arms down).
    pub fn rotate_subtree(&mut self, root: usize, rot: Quat) {
        let pivot = self.world_pos[root];
        for b in self.descendants(root) {
            self.world_pos[b] = pivot + rot * (self.world_pos[b] - pivot);
            self.world_rot[b] = rot * self.world_rot[b];
        }
    }

    /// Gives every bone a world rotation whose local +X points down the bone (to its first
    /// child), the way Unity/Maya-style rigs are built. Leaves copy their parent's rotation.
    pub fn bones_along_x(&mut self) {
        for b in 0..self.names.len() {
            let child = self.parents.iter().position(|p| *p == Some(b));
            let rot = match child {
                Some(c) => {
                    let d = (self.world_pos[c] - self.world_pos[b]).normalize_or_zero();
                    if d == Vec3::ZERO {
                        Quat::IDENTITY
                    } else {
                        Quat::from_rotation_arc(Vec3::X, d)
                    }
                }
                None => self.parents[b]
                    .map(|p| self.world_rot[p])
                    .unwrap_or_default(),
            };
            self.world_rot[b] = rot;
        }
        // Leaves processed before their parent got a rotation: fix them up.
        for b in 0..self.names.len() {
            if !self.parents.contains(&Some(b)) {
                self.world_rot[b] = self.parents[b]
                    .map(|p| self.world_rot[p])
                    .unwrap_or_default();
            }
        }
    }

    /// The raw skeleton (bones in insertion order) with local rest transforms.
    pub fn raw(&self) -> RawSkeleton {
        let mut raw = RawSkeleton::default();
        for b in 0..self.names.len() {
            let (pp, pr) = match self.parents[b] {
                Some(p) => (self.world_pos[p], self.world_rot[p]),
                None => (Vec3::ZERO, Quat::IDENTITY),
            };
            let inv = pr.inverse();
            raw.add(
                self.names[b].clone(),
                self.parents[b],
                Transform {
                    translation: inv * (self.world_pos[b] - pp),
                    rotation: (inv * self.world_rot[b]).normalize(),
                },
            );
        }
        raw
    }

    /// Builds the skeleton and the labels indexed by its bone ids.
    pub fn build(&self) -> Option<(Skeleton, Vec<String>)> {
        let skel = Skeleton::build(&self.raw()).ok()?;
        let labels = skel
            .names()
            .iter()
            .map(|n| {
                self.find(n)
                    .map(|i| self.labels[i].clone())
                    .unwrap_or_default()
            })
            .collect();
        Some((skel, labels))
    }

    /// Copy with names replaced by `j0..jN` and child order shuffled (seeded, deterministic).
    pub fn anonymized(&self, seed: u64) -> Builder {
        let n = self.names.len();
        // Random keys; a parent must come before its children in the raw list, so sort by
        // (depth, key): children of one parent get a shuffled relative order.
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut keys = Vec::with_capacity(n);
        for _ in 0..n {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            keys.push(state);
        }
        let depth = |mut b: usize| {
            let mut d = 0;
            while let Some(p) = self.parents[b] {
                d += 1;
                b = p;
            }
            d
        };
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&b| (depth(b), keys[b]));
        let mut new_of = vec![0; n];
        for (new, &old) in order.iter().enumerate() {
            new_of[old] = new;
        }
        let mut out = Builder::default();
        for &old in &order {
            out.names.push(format!("j{}", new_of[old]));
            out.parents.push(self.parents[old].map(|p| new_of[p]));
            out.world_pos.push(self.world_pos[old]);
            out.world_rot.push(self.world_rot[old]);
            out.labels.push(self.labels[old].clone());
        }
        out
    }
}
