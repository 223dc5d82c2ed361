//! Footplant-synchronised resampling (seed 002; Heck, Kovar, Gleicher 2006): the graft's
//! clock is warped piecewise-linearly so that its footplants (heel strikes, one foot after
//! the other) fall on the locomotion's. Between two matched plants the graft plays at the
//! ratio of the distances between them, clamped so it never plays slower than half or faster
//! than twice its speed; outside the matched plants it plays at the mean ratio.

use crate::analysis::Side;
use crate::footplant::{LegKind, PlantTrack};

/// A plant's start: which foot (kind, side, pair) lands, and when (frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlantEvent {
    /// The frame the plant starts at.
    pub frame: usize,
    /// The foot, as [`crate::footplant::Leg::key`].
    pub foot: (LegKind, Side, u8),
}

/// Every plant start of a track, in time order. A plant already under way at the first frame
/// is no landing and is left out.
pub fn plant_events(track: &PlantTrack) -> Vec<PlantEvent> {
    let mut events: Vec<PlantEvent> = (0..track.legs.len())
        .flat_map(|l| {
            let foot = track.legs[l].key();
            track
                .intervals(l)
                .into_iter()
                .filter(|r| r.start > 0)
                .map(move |r| PlantEvent {
                    frame: r.start,
                    foot,
                })
        })
        .collect();
    events.sort_by_key(|e| e.frame);
    events
}

/// Pairs the events of two clips outwards from an anchor pair (`lower[at.0]` ↔ `upper[at.1]`,
/// the same foot): each next landing is paired while both clips land the same foot. Where they
/// do not, one clip has an extra landing (a stutter step, a plant split in two): the shorter
/// of the two next intervals, relative to its clip's typical interval, is skipped once; a run
/// ends where that does not resynchronise them or either list ends. Returns (lower frame,
/// upper frame).
pub fn pair_from(
    lower: &[PlantEvent],
    upper: &[PlantEvent],
    at: (usize, usize),
) -> Vec<(usize, usize)> {
    let mut forward = walk(lower, upper, at, Direction::Forward);
    let mut backward = walk(lower, upper, at, Direction::Backward);
    backward.reverse();
    backward.pop();
    backward.append(&mut forward);
    backward
}

#[derive(Clone, Copy, PartialEq)]
enum Direction {
    Forward,
    Backward,
}

/// The median interval between consecutive landings, in frames (1 when fewer than two).
fn typical_gap(events: &[PlantEvent]) -> f64 {
    let mut gaps: Vec<usize> = events.windows(2).map(|w| w[1].frame - w[0].frame).collect();
    gaps.sort_unstable();
    gaps.get(gaps.len() / 2)
        .map(|&g| g.max(1) as f64)
        .unwrap_or(1.0)
}

fn walk(
    lower: &[PlantEvent],
    upper: &[PlantEvent],
    at: (usize, usize),
    dir: Direction,
) -> Vec<(usize, usize)> {
    let step = |i: usize, k: usize, len: usize| match dir {
        Direction::Forward => (i + k < len).then_some(i + k),
        Direction::Backward => i.checked_sub(k),
    };
    let (gl, gu) = (typical_gap(lower), typical_gap(upper));
    let gap = |e: &[PlantEvent], a: usize, b: usize| e[a].frame.abs_diff(e[b].frame) as f64;
    let mut pairs = vec![(lower[at.0].frame, upper[at.1].frame)];
    let (mut i, mut j) = at;
    while let (Some(ni), Some(nj)) = (step(i, 1, lower.len()), step(j, 1, upper.len())) {
        let next = if lower[ni].foot == upper[nj].foot {
            Some((ni, nj))
        } else {
            // Skip the shorter interval's landing, if that brings the feet back in step.
            let skip_lower = gap(lower, i, ni) / gl < gap(upper, j, nj) / gu;
            let (si, sj) = if skip_lower {
                (step(i, 2, lower.len()), Some(nj))
            } else {
                (Some(ni), step(j, 2, upper.len()))
            };
            match (si, sj) {
                (Some(a), Some(b)) if lower[a].foot == upper[b].foot => Some((a, b)),
                _ => None,
            }
        };
        let Some((a, b)) = next else { break };
        (i, j) = (a, b);
        pairs.push((lower[i].frame, upper[j].frame));
    }
    pairs
}

/// Slowest and fastest the graft may play relative to its own speed.
pub const SLOPE_RANGE: (f64, f64) = (0.5, 2.0);

/// The locomotion's time → the graft's time, piecewise linear.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeWarp {
    /// (locomotion secs, graft secs), increasing in both.
    knots: Vec<(f64, f64)>,
    /// Graft seconds per locomotion second outside the knots.
    outside: f64,
    /// The graft's last frame time (the warp's values are clamped to it).
    graft_end_secs: f64,
}

impl TimeWarp {
    /// A warp through matched frames (`pairs`: locomotion frame, graft frame), each segment's
    /// slope clamped to [`SLOPE_RANGE`] (the knots after a clamped segment move with it).
    pub fn from_pairs(
        pairs: &[(usize, usize)],
        lower_frame_secs: f64,
        upper_frame_secs: f64,
        graft_end_secs: f64,
    ) -> TimeWarp {
        let mut knots: Vec<(f64, f64)> = Vec::with_capacity(pairs.len());
        for &(l, u) in pairs {
            let (tl, tu) = (l as f64 * lower_frame_secs, u as f64 * upper_frame_secs);
            match knots.last() {
                None => knots.push((tl, tu)),
                Some(&(pl, pu)) if tl > pl => {
                    let slope = ((tu - pu) / (tl - pl)).clamp(SLOPE_RANGE.0, SLOPE_RANGE.1);
                    knots.push((tl, pu + slope * (tl - pl)));
                }
                Some(_) => {}
            }
        }
        let outside = match (knots.first(), knots.last()) {
            (Some(a), Some(b)) if b.0 > a.0 => (b.1 - a.1) / (b.0 - a.0),
            _ => 1.0,
        };
        TimeWarp {
            knots,
            outside,
            graft_end_secs: graft_end_secs.max(0.0),
        }
    }

    /// Graft seconds per locomotion second over the matched plants (1 without two of them).
    pub fn factor(&self) -> f64 {
        self.outside
    }

    /// The matched (locomotion, graft) times after clamping.
    pub fn knots(&self) -> &[(f64, f64)] {
        &self.knots
    }

    /// The unclamped graft time at locomotion time `t` (may lie outside the graft).
    fn raw(&self, t: f64) -> f64 {
        let Some(&first) = self.knots.first() else {
            return t;
        };
        let last = self.knots[self.knots.len() - 1];
        if t <= first.0 {
            return first.1 - (first.0 - t) * self.outside;
        }
        if t >= last.0 {
            return last.1 + (t - last.0) * self.outside;
        }
        let k = self.knots.partition_point(|k| k.0 <= t);
        let (a, b) = (self.knots[k - 1], self.knots[k]);
        a.1 + (t - a.0) * (b.1 - a.1) / (b.0 - a.0)
    }

    /// The graft time shown at locomotion time `t`, within the graft.
    pub fn at(&self, t: f64) -> f64 {
        self.raw(t).max(0.0).min(self.graft_end_secs)
    }

    /// Whether locomotion time `t` falls outside the graft (the graft's end frame is held).
    pub fn holds(&self, t: f64) -> bool {
        let r = self.raw(t);
        r < 0.0 || r > self.graft_end_secs
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(frame: usize, side: Side) -> PlantEvent {
        PlantEvent {
            frame,
            foot: (LegKind::Hind, side, 0),
        }
    }

    #[test]
    fn plants_land_on_plants_and_the_slope_is_clamped() {
        // Locomotion lands every 60 frames, the graft every 40 (it steps 1.5 times faster).
        let lower: Vec<_> = (0..5)
            .map(|k| ev(10 + 60 * k, [Side::Left, Side::Right][k % 2]))
            .collect();
        let upper: Vec<_> = (0..6)
            .map(|k| ev(5 + 40 * k, [Side::Right, Side::Left][k % 2]))
            .collect();
        // Anchor: lower's first left landing with upper's second event (a left one).
        let pairs = pair_from(&lower, &upper, (0, 1));
        assert_eq!(
            pairs,
            vec![(10, 45), (70, 85), (130, 125), (190, 165), (250, 205)]
        );
        let dt = 1.0 / 120.0;
        let w = TimeWarp::from_pairs(&pairs, dt, dt, 300.0 * dt);
        assert!((w.factor() - 40.0 / 60.0).abs() < 1e-9);
        for &(l, u) in &pairs {
            assert!((w.at(l as f64 * dt) - u as f64 * dt).abs() < 1e-9);
        }
        // Halfway between two plants: halfway between the graft's.
        assert!((w.at(100.0 * dt) - 105.0 * dt).abs() < 1e-9);
        // A graft stepping 3x faster is played at most at half speed.
        let fast = TimeWarp::from_pairs(&[(0, 0), (60, 20)], dt, dt, 100.0 * dt);
        assert!((fast.at(60.0 * dt) - 30.0 * dt).abs() < 1e-9);
        // Before the first knot at the mean ratio, then held at the graft's start.
        assert!(!w.holds(0.0));
        assert!((w.at(0.0) - (45.0 - 10.0 * 40.0 / 60.0) * dt).abs() < 1e-9);
        // Past the graft's end its last frame is held.
        assert!(w.holds(1000.0 * dt) && w.at(1000.0 * dt) == 300.0 * dt);
    }

    #[test]
    fn a_stutter_step_is_skipped_and_a_lasting_mismatch_stops_the_pairing() {
        use Side::{Left as L, Right as R};
        // The lower clip has an extra right landing 2 frames after one (a split plant).
        let lower = [ev(0, L), ev(10, R), ev(12, R), ev(20, L), ev(30, R)];
        let upper = [ev(3, L), ev(13, R), ev(23, L), ev(33, R)];
        assert_eq!(
            pair_from(&lower, &upper, (0, 0)),
            vec![(0, 3), (10, 13), (20, 23), (30, 33)]
        );
        // Both clips land the same foot twice in a row, out of step: no skip resynchronises.
        let lower = [ev(0, L), ev(10, R), ev(20, R), ev(30, R)];
        let upper = [ev(3, L), ev(13, R), ev(23, L), ev(33, L)];
        assert_eq!(pair_from(&lower, &upper, (0, 0)), vec![(0, 3), (10, 13)]);
        // Backwards from a later anchor.
        let lower = [ev(0, L), ev(10, R), ev(20, L)];
        let upper = [ev(5, R), ev(15, L), ev(25, R), ev(35, L)];
        assert_eq!(
            pair_from(&lower, &upper, (2, 3)),
            vec![(0, 15), (10, 25), (20, 35)]
        );
    }
}
