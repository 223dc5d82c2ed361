//! Order-free structural facts about a skeleton: main child, reach, subtree hashes, helpers.
//!
//! Everything here must be independent of child order (a shuffled copy of a skeleton must get
//! the same analysis), so ties are broken by geometry and canonical subtree hashes, never by
//! child index.

use glam::Vec3;

use crate::fk::world_transforms;
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// Per-bone structural facts.
pub(crate) struct Topology {
    /// Child continuing the bone's chain (the one leading to the farthest descendant).
    pub main: Vec<Option<BoneId>>,
    /// Longest path length (metres) from the bone down to a descendant.
    pub reach: Vec<f32>,
    /// Distance to the main child (0 for leaves).
    pub length: Vec<f32>,
    /// Order-free hash of the subtree's shape (topology only).
    pub hash: Vec<u64>,
    /// Number of bones in the subtree (itself included).
    pub size: Vec<usize>,
    /// Mean position of the subtree's joints.
    pub centroid: Vec<Vec3>,
}

/// World joint positions of `pose` (or the rest pose).
pub(crate) fn joint_positions(skeleton: &Skeleton, pose: Option<&Pose>) -> Vec<Vec3> {
    let rest;
    let pose = match pose {
        Some(p) if p.check(skeleton).is_ok() => p,
        _ => {
            rest = skeleton.rest_pose();
            &rest
        }
    };
    world_transforms(skeleton, pose)
        .iter()
        .map(|w| w.translation)
        .collect()
}

/// True when the joints (nearly) lie on one line: the rest pose carries no usable geometry.
pub(crate) fn is_degenerate(positions: &[Vec3]) -> bool {
    if positions.len() < 3 {
        return false;
    }
    let mean = positions.iter().copied().sum::<Vec3>() / positions.len() as f32;
    // Principal direction by a few power iterations on the covariance.
    let mut cov = [[0.0f32; 3]; 3];
    for p in positions {
        let d = *p - mean;
        let a = d.to_array();
        for (i, row) in cov.iter_mut().enumerate() {
            for (j, c) in row.iter_mut().enumerate() {
                *c += a[i] * a[j];
            }
        }
    }
    let m = glam::Mat3::from_cols_array_2d(&cov);
    let mut v = Vec3::new(0.577, 0.577, 0.577);
    for _ in 0..32 {
        v = (m * v).normalize_or_zero();
        if v == Vec3::ZERO {
            return true;
        }
    }
    let total: f32 = positions.iter().map(|p| (*p - mean).length_squared()).sum();
    let along: f32 = positions.iter().map(|p| (*p - mean).dot(v).powi(2)).sum();
    total <= f32::EPSILON || (total - along) / total < 1e-4
}

impl Topology {
    pub(crate) fn build(skeleton: &Skeleton, pos: &[Vec3]) -> Topology {
        let n = skeleton.num_bones();
        let mut t = Topology {
            main: vec![None; n],
            reach: vec![0.0; n],
            length: vec![0.0; n],
            hash: vec![0; n],
            size: vec![1; n],
            centroid: pos.to_vec(),
        };
        // Children have larger ids than parents, so a reverse sweep sees children first.
        for i in (0..n).rev() {
            let b = BoneId(i as u16);
            let mut best: Option<(f32, u64, BoneId)> = None;
            let mut hashes = Vec::new();
            let mut sum = pos[i];
            for &c in skeleton.children(b) {
                let seg = (pos[c.index()] - pos[i]).length();
                let r = seg + t.reach[c.index()];
                let h = t.hash[c.index()];
                let better = match best {
                    None => true,
                    // Longer reach wins; near-equal reach falls back to the hash, not order.
                    Some((br, bh, _)) => r > br + 1e-5 || ((r - br).abs() <= 1e-5 && h > bh),
                };
                if better {
                    best = Some((r, h, c));
                }
                hashes.push(h);
                t.size[i] += t.size[c.index()];
                sum += t.centroid[c.index()] * t.size[c.index()] as f32;
            }
            if let Some((r, _, c)) = best {
                t.reach[i] = r;
                t.main[i] = Some(c);
                t.length[i] = (pos[c.index()] - pos[i]).length();
            }
            t.centroid[i] = sum / t.size[i] as f32;
            hashes.sort_unstable();
            let mut h: u64 = 0xcbf2_9ce4_8422_2325;
            for x in std::iter::once(hashes.len() as u64).chain(hashes) {
                h ^= x;
                h = h.wrapping_mul(0x0000_0100_0000_01b3).rotate_left(17);
            }
            t.hash[i] = h;
        }
        t
    }

    /// Follows main children from `start` to a leaf.
    /// The first joints down the main chains of twins `a` and `b` that lie more than `tol`
    /// apart in `pos`: the twins themselves unless they coincide (zero-length hip or thigh
    /// helpers on one joint). The last pair reached when the chains never part.
    pub(crate) fn parted(&self, pos: &[Vec3], a: BoneId, b: BoneId, tol: f32) -> (BoneId, BoneId) {
        let (mut x, mut y) = (a, b);
        // Each step goes one bone deeper, so the chains end within the bone count.
        for _ in 0..self.main.len() {
            if (pos[x.index()] - pos[y.index()]).length() > tol {
                break;
            }
            match (self.main[x.index()], self.main[y.index()]) {
                (Some(cx), Some(cy)) => (x, y) = (cx, cy),
                _ => break,
            }
        }
        (x, y)
    }

    pub(crate) fn chain(&self, start: BoneId) -> Vec<BoneId> {
        let mut out = vec![start];
        let mut b = start;
        while let Some(c) = self.main[b.index()] {
            out.push(c);
            b = c;
        }
        out
    }
}
