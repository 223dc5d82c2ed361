//! What every phase of the role analysis reads: the skeleton in its posture, its topology,
//! names and axes ([`Ctx`]), the limbs found on the centerline ([`Limb`]), and the role table
//! being filled ([`Builder`]).

use glam::Vec3;

use super::names::NameInfo;
use super::topology::Topology;
use super::vocabulary::{Role, SectionKind};
use super::{BoneRole, Doubt, Section, Side};
use crate::skeleton::{BoneId, Skeleton};

/// One pair of limbs (or a lone side chain) hanging off a central bone.
pub(super) struct Limb {
    pub(super) parent: BoneId,
    /// Members: (chain root, side). Usually two, mirror images.
    pub(super) members: Vec<(BoneId, Side)>,
    pub(super) reach: f32,
    pub(super) ground: bool,
    /// Height of its lowest joint (a detached foot continuing it included).
    pub(super) low: f32,
    pub(super) height: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum LimbKind {
    Leg,
    Arm,
    Wing,
    Appendage,
}

pub(super) struct Ctx<'a> {
    pub(super) skel: &'a Skeleton,
    /// Per leaf: the detached bone continuing it (an IK foot at the end of a shin).
    pub(super) extension: &'a [Option<BoneId>],
    /// Control bones beside the body (see `detached`).
    pub(super) detached: &'a [bool],
    pub(super) pos: &'a [Vec3],
    pub(super) topo: &'a Topology,
    pub(super) names: &'a [NameInfo],
    /// Per bone, whether its local rotation changes over the view's motion; `None` without a
    /// motion of at least two frames (no evidence either way).
    pub(super) moving: Option<&'a [bool]>,
    /// World joint positions of frames sampled from the motion (empty without one).
    pub(super) samples: &'a [Vec<Vec3>],
    pub(super) up: Vec3,
    pub(super) forward: Vec3,
    pub(super) size: f32,
}

impl Ctx<'_> {
    pub(super) fn h(&self, b: BoneId) -> f32 {
        self.pos[b.index()].dot(self.up)
    }
    pub(super) fn subtree(&self, b: BoneId) -> impl Iterator<Item = BoneId> {
        let s = b.index();
        (s..s + self.topo.size[s]).map(|i| BoneId(i as u16))
    }
    pub(super) fn is_leaf(&self, b: BoneId) -> bool {
        self.skel.children(b).is_empty()
    }
    /// A leaf that only shadows its parent: coincident with it, lying on the parent's own
    /// segment (twist bones), or named as a helper.
    pub(super) fn is_shadow(&self, b: BoneId) -> bool {
        if self.detached[b.index()] {
            return true;
        }
        if !self.is_leaf(b) {
            return false;
        }
        let Some(p) = self.skel.parent(b) else {
            return false;
        };
        let pp = self.pos[p.index()];
        let pb = self.pos[b.index()];
        if (pb - pp).length() < 1e-3 * self.size.max(1e-3) {
            return true;
        }
        if let Some(m) = self.topo.main[p.index()] {
            if m != b {
                let seg = self.pos[m.index()] - pp;
                let t = (pb - pp).dot(seg) / seg.length_squared().max(1e-12);
                let off = (pb - pp - seg * t).length();
                if (0.0..=1.0).contains(&t) && off < 0.01 * self.size {
                    return true;
                }
            }
        }
        self.names[b.index()].helper
    }
    /// The bone sits exactly on its parent's joint.
    pub(super) fn is_coincident(&self, b: BoneId) -> bool {
        match self.skel.parent(b) {
            Some(p) => {
                (self.pos[b.index()] - self.pos[p.index()]).length() < 1e-3 * self.size.max(1e-3)
            }
            None => false,
        }
    }

    /// A twist bone: a leaf lying inside its parent's segment, or named so.
    pub(super) fn is_twist(&self, b: BoneId) -> bool {
        let nm = &self.names[b.index()];
        if nm.tokens.iter().any(|t| t == "twist" || t == "roll") {
            return true;
        }
        let Some(p) = self.skel.parent(b) else {
            return false;
        };
        let Some(m) = self.topo.main[p.index()] else {
            return false;
        };
        if m == b || !self.is_leaf(b) {
            return false;
        }
        let pp = self.pos[p.index()];
        let seg = self.pos[m.index()] - pp;
        let d = self.pos[b.index()] - pp;
        let t = d.dot(seg) / seg.length_squared().max(1e-12);
        (0.05..=0.95).contains(&t) && (d - seg * t).length() < 0.01 * self.size
    }

    pub(super) fn significant_children(&self, b: BoneId) -> Vec<BoneId> {
        self.skel
            .children(b)
            .iter()
            .copied()
            .filter(|&c| !self.is_shadow(c))
            .collect()
    }
}

/// The role table being filled: roles per bone and the sections they belong to.
pub(super) struct Builder {
    pub(super) roles: Vec<BoneRole>,
    pub(super) sections: Vec<Section>,
    pub(super) lengths: Vec<f32>,
    /// Readings nearly made instead (see [`Doubt`]).
    pub(super) doubts: Vec<Doubt>,
}

impl Builder {
    /// An empty table: every bone unknown.
    pub(super) fn new(lengths: Vec<f32>) -> Builder {
        Builder {
            roles: vec![BoneRole::unknown(); lengths.len()],
            sections: Vec::new(),
            lengths,
            doubts: Vec::new(),
        }
    }

    /// Adds a section of `bones` (body outwards); each bone gets its section, side, limb index
    /// and position along it (by length). Returns the section's index.
    pub(super) fn add_section(
        &mut self,
        kind: SectionKind,
        side: Side,
        limb: u8,
        bones: Vec<BoneId>,
        parent: Option<usize>,
        ground: bool,
    ) -> usize {
        let total: f32 = bones.iter().map(|b| self.lengths[b.index()]).sum();
        let idx = self.sections.len();
        let mut acc = 0.0;
        let nb = bones.len().max(1) as f32;
        for (j, b) in bones.iter().enumerate() {
            let r = &mut self.roles[b.index()];
            r.section = Some(idx as u16);
            r.side = side;
            r.limb = limb;
            r.position = if total > 1e-6 {
                acc / total
            } else {
                j as f32 / nb
            };
            acc += self.lengths[b.index()];
        }
        self.sections.push(Section {
            kind,
            side,
            limb,
            bones,
            length: total,
            parent,
            ground,
        });
        idx
    }

    /// Sets one bone's role and confidence.
    pub(super) fn set(&mut self, b: BoneId, role: Role, confidence: f32) {
        let r = &mut self.roles[b.index()];
        r.role = role;
        r.confidence = confidence;
    }

    /// Section of a bone, if placed in one.
    pub(super) fn section_of(&self, b: BoneId) -> Option<usize> {
        self.roles[b.index()].section.map(|s| s as usize)
    }
}
