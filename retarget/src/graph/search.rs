//! Finding transitions: pairs of frames that look alike (local minima of the frame distance
//! below the threshold), without computing all N² distances at full resolution.
//!
//! The search is coarse to fine and pruned:
//!
//! 1. **Coarse grid.** Distances are evaluated only between every `stride`-th frame
//!    (`stride` = frames per 1/30 s: motion barely changes within 1/30 s, which is why Kovar
//!    et al. worked at that rate), i.e. on 1/stride² of the pairs, and each unordered pair
//!    once (the upper triangle), against a looser bound (threshold × `1 + COARSE_MARGIN`)
//!    so a minimum that falls between grid frames is not missed.
//! 2. **Pruned distances.** Every distance gives up as soon as its partial sum passes the
//!    bound ([`super::features::distance_sq_bounded`]); pairs far apart stop after the first
//!    block of points.
//! 3. **Refinement.** From each surviving grid pair on a valley floor (no larger than its
//!    neighbours across the diagonal), steepest descent over full-resolution neighbours,
//!    kept within one grid step of its start, finds the exact local minimum, which is kept
//!    when it is a minimum over its whole neighbourhood (radius ≈ 1/15 s, Kovar's 5 × 5 at
//!    30 Hz; nearest ring first, so most candidates are turned down after a few distances)
//!    and below the threshold. Descents that meet remember each cell's move.
//! 4. **Two threads.** The grid rows are cut into two bands of equal work, searched apart
//!    and merged (a minimum found from both is the same pair with the same distance).
//!
//! Pairs within one clip closer than `min_gap` frames are never transitions (they are the
//! clip itself).

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

use super::features::{distance_sq_bounded, rms, squared_bound, ClipFeatures, DIM};

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
    /// Offsets of the local-minimum neighbourhood, nearest ring first: a closer pair, when
    /// there is one, is most often right next to the candidate, so most rejections stop early.
    /// The first `NEIGHBOURS.len()` are the eight neighbours.
    around: Vec<(isize, isize)>,
    /// Per clip and frame: how far (Euclidean, not squared) the frame's vector is from any
    /// frame within one grid step of it. A descent never ends more than a grid step from its
    /// start on either axis, so by the triangle inequality it cannot end below
    /// √d − reach(a) − reach(b): when that is above the threshold, the descent is not made.
    reach: Vec<Vec<f32>>,
}

/// For every frame of `clip`: the largest distance from its vector to the vector of a frame
/// at most `step` frames away (infinite where the frame has no vector).
fn reach_of(clip: &ClipFeatures, step: usize) -> Vec<f32> {
    (0..clip.len)
        .map(|i| {
            let Some(v) = clip.get(i) else {
                return f32::INFINITY;
            };
            (i.saturating_sub(step)..=i + step)
                .filter_map(|j| clip.get(j))
                .map(|w| distance_sq_bounded(v, w, f32::INFINITY).sqrt())
                .fold(0.0, f32::max)
        })
        .collect()
}

/// A cell of the distance matrix: two (clip, frame) pairs.
type Cell = ((usize, usize), (usize, usize));

/// Steepest-descent moves already worked out: a cell and its distance → its lowest neighbour
/// (itself at a local minimum). Neighbouring floor cells of one valley descend through the
/// same cells; the move from a cell does not depend on where the descent started.
type Moves = HashMap<Cell, (Cell, f32), BuildHasherDefault<CellHasher>>;

/// Minima already reached (a descent from another floor cell of the same valley ends there
/// too).
type Seen = HashSet<Cell, BuildHasherDefault<CellHasher>>;

/// A multiply-rotate hash for cells (four small integers): the maps above are looked up for
/// every step of every descent, and the standard SipHash (made to resist crafted keys, which
/// frame indices are not) cost as much as the distances the memo saves.
#[derive(Default, Clone, Copy)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        bytes.iter().for_each(|&b| self.write_usize(b as usize));
    }

    fn write_usize(&mut self, n: usize) {
        self.0 = (self.0.rotate_left(5) ^ n as u64).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

impl Db<'_> {
    fn new(clips: &[ClipFeatures], p: SearchParams) -> Db<'_> {
        let r = p.radius as isize;
        let mut around: Vec<(isize, isize)> = (-r..=r)
            .flat_map(|da| (-r..=r).map(move |db| (da, db)))
            .filter(|&o| o != (0, 0))
            .collect();
        around.sort_by_key(|&(da, db)| da.abs().max(db.abs()));
        let reach = clips.iter().map(|c| reach_of(c, p.stride.max(1))).collect();
        Db {
            clips,
            p,
            around,
            reach,
        }
    }

    /// True when no descent from `(a, b)` at squared distance `d` can end at or below the
    /// squared distance `fine` (see [`Db::reach`]; the margin covers rounding).
    fn cannot_descend_below(&self, (a, b): Cell, d: f32, fine: f32) -> bool {
        let r = |(c, f): (usize, usize)| self.reach[c].get(f).copied().unwrap_or(f32::INFINITY);
        d.sqrt() - r(a) - r(b) > fine.sqrt() * (1.0 + 1e-3)
    }

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

    /// The lowest of the eight neighbours of `(a, b)` (at distance `d`), or the cell itself
    /// when none is lower.
    fn lowest_neighbour(&self, (a, b): Cell, d: f32) -> (Cell, f32) {
        let mut best = ((a, b), d);
        for (da, db) in NEIGHBOURS {
            let (Some(na), Some(nb)) = (shift(a, da), shift(b, db)) else {
                continue;
            };
            if let Some(nd) = self.dist_sq(na, nb, best.1) {
                if nd < best.1 {
                    best = ((na, nb), nd);
                }
            }
        }
        best
    }

    /// Steepest descent to a local minimum at full resolution, staying within `stride` frames
    /// of the start on both axes: a minimum farther away is the business of the grid cell
    /// nearer to it (`None` when the descent would leave).
    fn descend(&self, start: Cell, d: f32, moves: &mut Moves) -> Option<Pair> {
        let (mut cell, mut d) = (start, d);
        let reach = self.p.stride.max(1);
        loop {
            let (next, nd) = *moves
                .entry(cell)
                .or_insert_with(|| self.lowest_neighbour(cell, d));
            if nd >= d {
                return Some((cell.0, cell.1, d));
            }
            (cell, d) = (next, nd);
            let (a, b) = cell;
            if a.1.abs_diff(start.0 .1) > reach || b.1.abs_diff(start.1 .1) > reach {
                return None;
            }
        }
    }

    /// True when no pair within the radius is closer; the first `skip` offsets of
    /// [`Db::around`] are taken as checked (a descent's end is no larger than its eight
    /// neighbours).
    fn is_minimum(&self, a: (usize, usize), b: (usize, usize), d: f32, skip: usize) -> bool {
        !self
            .around
            .get(skip..)
            .unwrap_or_default()
            .iter()
            .any(|&(da, db)| {
                let (Some(na), Some(nb)) = (shift(a, da), shift(b, db)) else {
                    return false;
                };
                self.dist_sq(na, nb, d).is_some_and(|nd| nd < d)
            })
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

/// Threads the coarse scan is split over (at most; fewer when the machine has fewer cores).
const SEARCH_THREADS: usize = 2;

/// Finds all similar pairs (each unordered pair once, `a` before `b` in clip order), calling
/// `progress` with the fraction done now and then.
///
/// The grid rows are split into bands of equal work (row `k` costs `G − k` cells: only the
/// upper triangle is scanned) searched on [`SEARCH_THREADS`] threads; each band finds the
/// minima reached from its rows, and the bands' results are merged, so the result does not
/// depend on the split.
pub fn find_similar(
    clips: &[ClipFeatures],
    p: SearchParams,
    progress: &mut dyn FnMut(f32),
) -> Vec<Similar> {
    let db = Db::new(clips, p);
    let grid = Grid::new(clips, p.stride);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bands = equal_work_bands(grid.at.len(), SEARCH_THREADS.min(cores));
    let mut out = std::thread::scope(|s| {
        let (db, grid) = (&db, &grid);
        let others: Vec<_> = bands[1..]
            .iter()
            .map(|band| {
                let band = band.clone();
                s.spawn(move || scan_band(db, grid, band, &mut |_| {}))
            })
            .collect();
        // This thread takes the first band and reports progress (the bands take about as long).
        let mut out = scan_band(db, grid, bands[0].clone(), progress);
        for h in others {
            match h.join() {
                Ok(found) => out.extend(found),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        out
    });
    progress(1.0);
    out.sort_by_key(|x| (x.a, x.b));
    // A minimum reached from rows of two bands is found twice, with the same distance.
    out.dedup_by_key(|x| (x.a, x.b));
    out
}

/// `parts` contiguous ranges of `0..g` with about equal upper-triangle area (row `k` holds
/// `g − k` cells): boundaries at `g · (1 − √(1 − i / parts))`.
fn equal_work_bands(g: usize, parts: usize) -> Vec<std::ops::Range<usize>> {
    let parts = parts.max(1);
    let edge = |i: usize| {
        let f = 1.0 - (1.0 - i as f64 / parts as f64).sqrt();
        ((g as f64 * f).round() as usize).min(g)
    };
    (0..parts).map(|i| edge(i)..edge(i + 1)).collect()
}

/// The coarse grid: every `stride`-th frame with a vector, and those vectors packed one after
/// the other, so that a row of the coarse pass streams through memory instead of striding
/// over the whole database.
struct Grid {
    at: Vec<(usize, usize)>,
    packed: Vec<f32>,
}

impl Grid {
    fn new(clips: &[ClipFeatures], stride: usize) -> Grid {
        let at: Vec<(usize, usize)> = clips
            .iter()
            .enumerate()
            .flat_map(|(c, f)| f.valid_range().step_by(stride.max(1)).map(move |i| (c, i)))
            .collect();
        let packed = at
            .iter()
            .flat_map(|&(c, i)| clips[c].get(i).unwrap_or_default())
            .copied()
            .collect();
        Grid { at, packed }
    }

    fn vector(&self, k: usize) -> &[f32] {
        self.packed.get(k * DIM..(k + 1) * DIM).unwrap_or_default()
    }
}

/// Three coarse rows of the grid, kept in a ring by row index (row `r` in slot `r % 3`):
/// rows `k − 1`, `k` and `k + 1` are what tells a coarse valley floor, and the G × G matrix
/// is never held. Row `r` is only filled from column `r − 1` on: the scan reads row `k` right
/// of the diagonal and its neighbours one column beyond, never further left.
struct CoarseRows {
    slots: [Vec<f32>; 3],
    held: [usize; 3],
    bound: f32,
}

impl CoarseRows {
    fn new(g: usize, bound: f32) -> CoarseRows {
        CoarseRows {
            slots: std::array::from_fn(|_| vec![f32::INFINITY; g]),
            held: [usize::MAX; 3],
            bound,
        }
    }

    fn ensure(&mut self, db: &Db, grid: &Grid, r: usize) {
        let slot = r % 3;
        if self.held[slot] == r {
            return;
        }
        let row = &mut self.slots[slot];
        let (a, va) = (grid.at[r], grid.vector(r));
        let from = r.saturating_sub(1);
        for (b, cell) in row.iter_mut().enumerate().skip(from) {
            let d = if db.allowed(a, grid.at[b]) {
                distance_sq_bounded(va, grid.vector(b), self.bound)
            } else {
                f32::INFINITY
            };
            *cell = if d <= self.bound { d } else { f32::INFINITY };
        }
        self.held[slot] = r;
    }

    fn row(&self, r: usize) -> &[f32] {
        &self.slots[r % 3]
    }
}

/// The search from grid rows `band`: coarse cells right of the diagonal on a valley floor,
/// descended to full-resolution minima below the threshold.
fn scan_band(
    db: &Db,
    grid: &Grid,
    band: std::ops::Range<usize>,
    progress: &mut dyn FnMut(f32),
) -> Vec<Similar> {
    let fine = squared_bound(db.p.threshold);
    let mut rows = CoarseRows::new(
        grid.at.len(),
        squared_bound(db.p.threshold * (1.0 + COARSE_MARGIN)),
    );
    let mut seen = Seen::default();
    let mut moves = Moves::default();
    let mut out = Vec::new();
    for k in band.clone() {
        // Neighbour rows across a clip boundary do not count.
        let at = &grid.at;
        let same = |r: usize| at.get(r).is_some_and(|x| x.0 == at[k].0);
        let prev = k.checked_sub(1).filter(|&r| same(r));
        let next = Some(k + 1).filter(|&r| same(r));
        for r in [prev, Some(k), next].into_iter().flatten() {
            rows.ensure(db, grid, r);
        }
        let (prev, next) = (prev.map(|r| rows.row(r)), next.map(|r| rows.row(r)));
        for (b, &d) in rows.row(k).iter().enumerate().skip(k + 1) {
            if !d.is_finite()
                || !on_valley_floor(prev, next, at, b, d)
                || db.cannot_descend_below((at[k], at[b]), d, fine)
            {
                continue;
            }
            let Some((ma, mb, md)) = db.descend((at[k], at[b]), d, &mut moves) else {
                continue;
            };
            if md > fine || !seen.insert((ma, mb)) || !db.is_minimum(ma, mb, md, NEIGHBOURS.len()) {
                continue;
            }
            out.push(Similar {
                a: ma,
                b: mb,
                distance: rms(md),
            });
        }
        if k % 64 == 0 {
            progress((k - band.start) as f32 / band.len().max(1) as f32);
        }
    }
    out
}

/// True when coarse cell (k, b) (value `d`) lies on a valley floor: no larger than its two
/// neighbours across the diagonal ((k − 1, b + 1) in `prev`, (k + 1, b − 1) in `next`).
/// Similar stretches of motion make valleys along the diagonal; their floor rarely lies on
/// grid frames, so a full 3 × 3 minimum test on the grid misses minima, while descending from
/// every floor cell finds each of them (neighbours across a clip boundary do not count).
fn on_valley_floor(
    prev: Option<&[f32]>,
    next: Option<&[f32]>,
    grid: &[(usize, usize)],
    b: usize,
    d: f32,
) -> bool {
    let clip = grid[b].0;
    let lower = |row: Option<&[f32]>, nb: Option<usize>| match (row, nb) {
        (Some(row), Some(nb)) if nb < grid.len() && grid[nb].0 == clip => row[nb] < d,
        _ => false,
    };
    !(lower(prev, Some(b + 1)) || lower(next, b.checked_sub(1)))
}

/// The exhaustive reference: every pair at full resolution, local minima over the same
/// neighbourhood. O(N²); for tests that judge [`find_similar`] against it.
pub fn find_similar_exhaustive(clips: &[ClipFeatures], p: SearchParams) -> Vec<Similar> {
    let db = Db::new(clips, p);
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
            if d <= fine && db.is_minimum(a, b, d, 0) {
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

#[cfg(test)]
mod tests {
    use super::equal_work_bands;

    /// The bands cover the rows in order, without gaps, and hold about equal shares of the
    /// upper triangle (row `k` holds `g − k` cells): within one row's cells of each other.
    #[test]
    fn bands_split_the_triangle_evenly() {
        for (g, parts) in [(0, 2), (1, 2), (7, 2), (2540, 2), (2540, 3), (100, 1)] {
            let bands = equal_work_bands(g, parts);
            assert_eq!(bands.len(), parts);
            assert_eq!(bands.first().map(|b| b.start), Some(0));
            assert_eq!(bands.last().map(|b| b.end), Some(g));
            assert!(bands.windows(2).all(|w| w[0].end == w[1].start));
            let work: Vec<usize> = bands
                .iter()
                .map(|b| b.clone().map(|k| g - k).sum())
                .collect();
            let (lo, hi) = (work.iter().min(), work.iter().max());
            assert!(
                hi.zip(lo).is_some_and(|(h, l)| h - l <= g),
                "{g}/{parts}: {work:?}"
            );
        }
    }
}
