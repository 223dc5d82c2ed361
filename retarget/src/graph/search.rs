//! Finding transitions: pairs of frames that look alike (local minima of the frame distance
//! below the threshold), without computing all N² distances at full resolution.
//!
//! The search is coarse to fine and pruned:
//!
//! 1. **Coarse grid.** Distances are evaluated only between every `stride`-th frame
//!    (`stride` = frames per 1/30 s: motion barely changes within 1/30 s, which is why Kovar
//!    et al. worked at that rate), i.e. on 1/stride² of the pairs, against a looser bound
//!    (threshold × `1 + COARSE_MARGIN`) so a minimum that falls between grid frames is not
//!    missed.
//! 2. **Pruned distances.** Every distance gives up as soon as its partial sum passes the
//!    bound ([`super::features::distance_sq_bounded`]); most pairs in a database are far
//!    apart and stop after the first few points.
//! 3. **Refinement.** From each surviving grid pair on a valley floor (no larger than its
//!    neighbours across the diagonal), steepest descent over full-resolution neighbours,
//!    kept within one grid step of its start, finds the exact local minimum, which is kept when it is a minimum over its
//!    whole neighbourhood (radius ≈ 1/15 s, Kovar's 5 × 5 at 30 Hz) and below the threshold.
//!
//! Pairs within one clip closer than `min_gap` frames are never transitions (they are the
//! clip itself).

use std::collections::HashSet;

use super::features::{distance_sq_bounded, rms, squared_bound, ClipFeatures};

/// How much looser the coarse bound is than the threshold (distance ratio).
const COARSE_MARGIN: f32 = 0.5;

/// One pair of similar frames: `(clip, frame)` twice, and their distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similar {
    /// First frame (clip index, frame index).
    pub a: (usize, usize),
    /// Second frame.
    pub b: (usize, usize),
    /// Frame distance ([`super::features::rms`]).
    pub distance: f32,
}

/// Search parameters in frames.
#[derive(Debug, Clone, Copy)]
pub struct SearchParams {
    /// Grid step of the coarse pass.
    pub stride: usize,
    /// Radius of the local-minimum neighbourhood.
    pub radius: usize,
    /// Same-clip pairs closer than this are skipped.
    pub min_gap: usize,
    /// Distance threshold (leg lengths, RMS per point).
    pub threshold: f32,
}

struct Db<'a> {
    clips: &'a [ClipFeatures],
    p: SearchParams,
}

impl Db<'_> {
    fn allowed(&self, a: (usize, usize), b: (usize, usize)) -> bool {
        a.0 != b.0 || a.1.abs_diff(b.1) >= self.p.min_gap.max(1)
    }

    fn dist_sq(&self, a: (usize, usize), b: (usize, usize), bound: f32) -> Option<f32> {
        if !self.allowed(a, b) {
            return None;
        }
        let va = self.clips[a.0].get(a.1)?;
        let vb = self.clips[b.0].get(b.1)?;
        Some(distance_sq_bounded(va, vb, bound))
    }

    /// Steepest descent to a local minimum at full resolution, staying within `stride` frames
    /// of the start on both axes: a minimum farther away is the business of the grid cell
    /// nearer to it (`None` when the descent would leave).
    fn descend(&self, start: ((usize, usize), (usize, usize)), d: f32) -> Option<Pair> {
        let ((mut a, mut b), mut d) = (start, d);
        let reach = self.p.stride.max(1);
        loop {
            let mut best = (a, b, d);
            for (da, db) in NEIGHBOURS {
                let (Some(na), Some(nb)) = (shift(a, da), shift(b, db)) else {
                    continue;
                };
                if let Some(nd) = self.dist_sq(na, nb, best.2) {
                    if nd < best.2 {
                        best = (na, nb, nd);
                    }
                }
            }
            if best.2 >= d {
                return Some((a, b, d));
            }
            (a, b, d) = best;
            if a.1.abs_diff(start.0 .1) > reach || b.1.abs_diff(start.1 .1) > reach {
                return None;
            }
        }
    }

    /// True when no pair within the radius is closer.
    fn is_minimum(&self, a: (usize, usize), b: (usize, usize), d: f32) -> bool {
        let r = self.p.radius as isize;
        for da in -r..=r {
            for db in -r..=r {
                let (Some(na), Some(nb)) = (shift(a, da), shift(b, db)) else {
                    continue;
                };
                if (da, db) == (0, 0) {
                    continue;
                }
                if self.dist_sq(na, nb, d).is_some_and(|nd| nd < d) {
                    return false;
                }
            }
        }
        true
    }
}

type Pair = ((usize, usize), (usize, usize), f32);

const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

fn shift((c, f): (usize, usize), d: isize) -> Option<(usize, usize)> {
    Some((c, f.checked_add_signed(d)?))
}

/// Finds all similar pairs (each unordered pair once, `a` before `b` in clip order), calling
/// `progress` with the fraction done now and then.
pub fn find_similar(
    clips: &[ClipFeatures],
    p: SearchParams,
    progress: &mut dyn FnMut(f32),
) -> Vec<Similar> {
    let db = Db { clips, p };
    let grid: Vec<(usize, usize)> = clips
        .iter()
        .enumerate()
        .flat_map(|(c, f)| {
            f.valid_range()
                .step_by(p.stride.max(1))
                .map(move |i| (c, i))
        })
        .collect();
    let coarse = squared_bound(p.threshold * (1.0 + COARSE_MARGIN));
    let fine = squared_bound(p.threshold);
    let g = grid.len();
    // Three coarse rows at a time (k − 1, k, k + 1): enough to tell a coarse local minimum
    // without holding the G × G matrix.
    let mut rows = [
        vec![f32::INFINITY; g],
        vec![f32::INFINITY; g],
        vec![f32::INFINITY; g],
    ];
    let fill = |k: usize, row: &mut [f32]| {
        for (b, v) in row.iter_mut().enumerate() {
            *v = match db.dist_sq(grid[k], grid[b], coarse) {
                Some(d) if d <= coarse => d,
                _ => f32::INFINITY,
            };
        }
    };
    if g > 0 {
        fill(0, &mut rows[1]);
    }
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for k in 0..g {
        rows.rotate_left(1);
        // rows[0] = k − 1, rows[1] = k, rows[2] = k + 1 (when in the same clip).
        let next_same = k + 1 < g && grid[k + 1].0 == grid[k].0;
        if next_same {
            fill(k + 1, &mut rows[2]);
        } else {
            rows[2].fill(f32::INFINITY);
        }
        if k == 0 || grid[k - 1].0 != grid[k].0 {
            rows[0].fill(f32::INFINITY);
        }
        for b in k + 1..g {
            let d = rows[1][b];
            if !d.is_finite() || !coarse_minimum(&rows, &grid, b, d) {
                continue;
            }
            let Some((ma, mb, md)) = db.descend((grid[k], grid[b]), d) else {
                continue;
            };
            if md > fine || !seen.insert((ma, mb)) || !db.is_minimum(ma, mb, md) {
                continue;
            }
            out.push(Similar {
                a: ma,
                b: mb,
                distance: rms(md),
            });
        }
        if k % 64 == 0 {
            progress(k as f32 / g.max(1) as f32);
        }
    }
    progress(1.0);
    out.sort_by_key(|x| (x.a, x.b));
    out
}

/// True when coarse cell (k, b) (value `d`, in `rows[1]`) lies on a valley floor: no larger
/// than its two neighbours across the diagonal ((k − 1, b + 1) and (k + 1, b − 1)). Similar
/// stretches of motion make valleys along the diagonal; their floor rarely lies on grid
/// frames, so a full 3 × 3 minimum test on the grid misses minima, while descending from every
/// floor cell finds each of them (neighbours across a clip boundary do not count).
fn coarse_minimum(rows: &[Vec<f32>; 3], grid: &[(usize, usize)], b: usize, d: f32) -> bool {
    let clip = grid[b].0;
    let lower = |row: &[f32], nb: Option<usize>| {
        nb.filter(|&nb| nb < grid.len() && grid[nb].0 == clip)
            .is_some_and(|nb| row[nb] < d)
    };
    !(lower(&rows[0], Some(b + 1)) || lower(&rows[2], b.checked_sub(1)))
}

/// The exhaustive reference: every pair at full resolution, local minima over the same
/// neighbourhood. O(N²); for tests that judge [`find_similar`] against it.
pub fn find_similar_exhaustive(clips: &[ClipFeatures], p: SearchParams) -> Vec<Similar> {
    let db = Db { clips, p };
    let all: Vec<(usize, usize)> = clips
        .iter()
        .enumerate()
        .flat_map(|(c, f)| f.valid_range().map(move |i| (c, i)))
        .collect();
    let fine = squared_bound(p.threshold);
    let mut out = Vec::new();
    for (k, &a) in all.iter().enumerate() {
        for &b in &all[k + 1..] {
            let Some(d) = db.dist_sq(a, b, f32::INFINITY) else {
                continue;
            };
            if d <= fine && db.is_minimum(a, b, d) {
                out.push(Similar {
                    a,
                    b,
                    distance: rms(d),
                });
            }
        }
    }
    out
}
