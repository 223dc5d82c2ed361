//! Cluster graphs (seed 002): the frames of both clips, pooled, are clustered by pose distance
//! (k-means, deterministic farthest-point seeds), so cluster ids mean the same posture in
//! either clip. Each clip's graph has the clusters its frames visit as nodes and an edge for
//! every change of cluster from one frame to the next. A cluster both clips visit is shared:
//! a transition between the two motions exists there.

use super::features::{squared, Features};

/// k-means iterations (the assignment settles in far fewer on gait data).
const ITERATIONS: usize = 25;

/// Cluster labels of the frames of two clips, pooled.
#[derive(Debug, Clone, PartialEq)]
pub struct Clustering {
    /// Number of clusters.
    pub num_clusters: usize,
    /// Label per frame of the first clip.
    pub first: Vec<u16>,
    /// Label per frame of the second clip.
    pub second: Vec<u16>,
}

/// A clip's cluster graph.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterGraph {
    /// Frames per cluster (0: the clip never visits it).
    pub visits: Vec<usize>,
    /// (from, to, times): changes of cluster between consecutive frames.
    pub edges: Vec<(u16, u16, usize)>,
}

impl ClusterGraph {
    /// The graph of one clip's labels among `num_clusters`.
    pub fn new(labels: &[u16], num_clusters: usize) -> ClusterGraph {
        let mut visits = vec![0; num_clusters];
        let mut edges: Vec<(u16, u16, usize)> = Vec::new();
        for (i, &l) in labels.iter().enumerate() {
            visits[l as usize] += 1;
            let Some(&prev) = i.checked_sub(1).and_then(|p| labels.get(p)) else {
                continue;
            };
            if prev == l {
                continue;
            }
            match edges.iter_mut().find(|e| e.0 == prev && e.1 == l) {
                Some(e) => e.2 += 1,
                None => edges.push((prev, l, 1)),
            }
        }
        ClusterGraph { visits, edges }
    }

    /// Clusters this graph and `other` both visit.
    pub fn shared(&self, other: &ClusterGraph) -> Vec<u16> {
        (0..self.visits.len().min(other.visits.len()))
            .filter(|&c| self.visits[c] > 0 && other.visits[c] > 0)
            .map(|c| c as u16)
            .collect()
    }
}

/// Clusters the frames of `a` and `b` together into at most `k` clusters.
pub fn cluster_pair(a: &Features, b: &Features, k: usize) -> Clustering {
    let dims = a.dims;
    let rows: Vec<&[f32]> = (0..a.num_frames())
        .map(|f| a.row(f))
        .chain((0..b.num_frames()).map(|f| b.row(f)))
        .collect();
    let k = k.clamp(1, rows.len().max(1)).min(u16::MAX as usize);
    let labels = if rows.is_empty() || dims == 0 || b.dims != dims {
        vec![0; rows.len()]
    } else {
        kmeans(&rows, dims, k)
    };
    let (first, second) = labels.split_at(a.num_frames());
    Clustering {
        num_clusters: k,
        first: first.to_vec(),
        second: second.to_vec(),
    }
}

/// Farthest-point seeds (the first frame, then the frame farthest from every seed so far),
/// then Lloyd iterations. Deterministic.
fn kmeans(rows: &[&[f32]], dims: usize, k: usize) -> Vec<u16> {
    let mut centres: Vec<Vec<f32>> = vec![rows[0].to_vec()];
    let mut nearest: Vec<f32> = rows.iter().map(|r| squared(r, rows[0])).collect();
    while centres.len() < k {
        let (far, d) =
            nearest.iter().enumerate().fold(
                (0, -1.0f32),
                |best, (i, &d)| if d > best.1 { (i, d) } else { best },
            );
        if d <= 0.0 {
            break;
        }
        centres.push(rows[far].to_vec());
        for (n, r) in nearest.iter_mut().zip(rows) {
            *n = n.min(squared(r, rows[far]));
        }
    }
    let mut labels = vec![0u16; rows.len()];
    for _ in 0..ITERATIONS {
        let mut changed = false;
        for (l, r) in labels.iter_mut().zip(rows) {
            let best = closest(&centres, r);
            changed |= *l != best;
            *l = best;
        }
        let mut sums = vec![vec![0.0f32; dims]; centres.len()];
        let mut counts = vec![0usize; centres.len()];
        for (&l, r) in labels.iter().zip(rows) {
            counts[l as usize] += 1;
            for (s, v) in sums[l as usize].iter_mut().zip(r.iter()) {
                *s += v;
            }
        }
        for ((c, s), &n) in centres.iter_mut().zip(sums).zip(&counts) {
            if n > 0 {
                *c = s.into_iter().map(|v| v / n as f32).collect();
            }
        }
        if !changed {
            break;
        }
    }
    labels
}

fn closest(centres: &[Vec<f32>], r: &[f32]) -> u16 {
    let mut best = (0u16, f32::INFINITY);
    for (i, c) in centres.iter().enumerate() {
        let d = squared(c, r);
        if d < best.1 {
            best = (i as u16, d);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feats(points: &[[f32; 2]]) -> Features {
        Features {
            dims: 2,
            data: points.iter().flatten().copied().collect(),
        }
    }

    #[test]
    fn two_clips_share_the_cluster_they_both_visit() {
        // Clip a visits blobs near (0,0) and (10,0); clip b visits (10,0) and (0,10).
        let a = feats(&[[0.0, 0.1], [0.1, 0.0], [10.0, 0.0], [10.1, 0.1]]);
        let b = feats(&[[9.9, 0.0], [10.0, 0.2], [0.0, 10.0], [0.2, 9.9]]);
        let c = cluster_pair(&a, &b, 3);
        assert_eq!(c.first[0], c.first[1]);
        assert_eq!(c.first[2], c.second[0]);
        assert_ne!(c.first[0], c.second[2]);
        let (ga, gb) = (
            ClusterGraph::new(&c.first, 3),
            ClusterGraph::new(&c.second, 3),
        );
        assert_eq!(ga.shared(&gb), vec![c.first[2]]);
        assert_eq!(ga.edges, vec![(c.first[0], c.first[2], 1)]);
    }

    #[test]
    fn fewer_distinct_frames_than_clusters_is_fine() {
        let a = feats(&[[1.0, 1.0], [1.0, 1.0]]);
        let b = feats(&[[1.0, 1.0]]);
        let c = cluster_pair(&a, &b, 8);
        assert!(c.first.iter().chain(&c.second).all(|&l| l == 0));
    }
}
