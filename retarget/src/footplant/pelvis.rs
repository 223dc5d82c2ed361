//! Pelvis height from the legs' reach: how far to move the body up or down so that the legs
//! whose feet have somewhere to be (a pinned foot, a foot about to land) are turned least
//! away from the animation.
//!
//! Two feet that must both stand rarely agree on the body's height once a rig's legs and feet
//! are proportioned differently from the performer's (a steep foot rolling onto its ball
//! raises its ankle less than the performer's did; a floor that is not flat under the
//! capture). Whatever height is chosen, the IK takes up the rest in the legs. A nearly
//! straight leg turns far to reach a centimetre farther or nearer (its reach changes with the
//! square of the knee's turn); a bent one little. So the height is the one that keeps the sum
//! of the squared turns of every such leg's thigh and shin smallest, each leg weighted by how
//! firmly its foot is held (a landing foot by how near its plant is), not the mean of the
//! feet's height gaps, which bends the straight leg as much as the bent one.

use glam::Vec3;

use super::ik::Chain;
use super::rig::MAX_FEET;
use super::search::least_within;

/// One leg's part: where the animation has it, and how far up (along the floor's normal) its
/// ankle must go with the body where the animation puts it.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LegReach {
    pub hip: Vec3,
    pub knee: Vec3,
    pub ankle: Vec3,
    /// The side the knee bends to (the animation's, or the remembered one for a straight leg).
    pub pole: Vec3,
    /// How far up the ankle must go.
    pub gap: f32,
    /// How far over the ground the ankle's goal stands from it (with the body where it is
    /// carried over the ground).
    pub aside: Vec3,
    /// How firmly its foot is held: 1 pinned, a landing foot's weight as it comes down.
    pub weight: f32,
    /// Hip to knee to ankle.
    pub length: f32,
}

/// What missing a goal costs, in radians of turn per leg length missed (a leg that cannot
/// reach is worse than any bend: 1 % of the leg costs as much as a 5.7° turn).
pub(super) const MISS_RAD_PER_LEG: f32 = 10.0;

/// How closely the body's height is searched, as a share of the shortest searched leg (0.9 µm
/// on a 0.9 m leg). The least turned height is often a kink, where one leg is at the IK's
/// full stretch and turns fastest with its reach (about 0.01° a micrometre on a 0.9 m leg):
/// at 10⁻⁵ a leg, bones came out up to 0.13° from a brute-force search's least. Near a smooth
/// minimum the parabola gets there in a few steps, and the summed cost (squared turns read
/// from `f32` cosines) cannot tell heights a few hundredths of a millimetre apart anyway.
pub(super) const HEIGHT_TOL_PER_LEG: f32 = 1e-6;

/// Most search steps after the coarse scan: a guard, the tolerance ends the search first.
const MAX_STEPS: usize = 40;

/// Coarse samples over the bracket (the cost of two legs need not have one minimum).
const SCAN: usize = 9;

/// One leg's part of the cost with what does not move with the body worked out once (its
/// bones, its goal from the hip, its reach): the search scores some twenty heights a frame.
#[derive(Debug, Clone, Copy, Default)]
struct Prepared {
    /// The animation's thigh and shin.
    thigh: Vec3,
    shin: Vec3,
    /// The ankle's goal, and the ankle, from the hip where the animation has it.
    goal: Vec3,
    ankle: Vec3,
    pole: Vec3,
    /// `None`: a bone of no length, the leg stays as it is.
    chain: Option<Chain>,
    /// What a length missed costs (radians per unit of the rig's length).
    miss: f32,
    weight: f32,
}

impl LegReach {
    fn prepared(&self, up: Vec3) -> Prepared {
        let goal = self.ankle + self.aside + up * self.gap;
        Prepared {
            thigh: self.knee - self.hip,
            shin: self.ankle - self.knee,
            goal: goal - self.hip,
            ankle: self.ankle - self.hip,
            pole: self.pole,
            chain: Chain::new(self.hip, self.knee, self.ankle),
            miss: MISS_RAD_PER_LEG / self.length.max(1e-6),
            weight: self.weight,
        }
    }
}

impl Prepared {
    /// How far the leg's thigh and shin turn (radians), and what it misses (in radians' worth),
    /// with the body moved up by `h` (the hip goes up, the goal stays).
    fn turns(&self, up: Vec3, h: f32) -> [f32; 3] {
        let to_goal = self.goal - up * h;
        // The bones' places alone: their rotations are not needed to score them.
        let placed = self.chain.and_then(|c| c.place(to_goal, self.pole));
        let (knee, ankle) = placed.unwrap_or((self.thigh, self.ankle));
        [
            self.thigh.angle_between(knee),
            self.shin.angle_between(ankle - knee),
            self.miss * (to_goal - ankle).length(),
        ]
    }

    /// The squared turns of the leg's thigh and shin (radians², plus what it misses) with the
    /// body moved up by `h`.
    fn cost(&self, up: Vec3, h: f32) -> f32 {
        let sq = |a: f32| if a.is_finite() { a * a } else { 0.0 };
        self.turns(up, h).iter().map(|&a| sq(a)).sum()
    }
}

fn total(legs: &[Prepared], up: Vec3, h: f32) -> f32 {
    legs.iter().map(|l| l.weight * l.cost(up, h)).sum()
}

/// The body's move up (negative: down) within `±limit` that keeps `legs`' weighted turns
/// smallest; `None` when no leg has weight. One leg alone is met exactly (its gap).
pub(super) fn best_height(legs: &[LegReach], up: Vec3, limit: f32) -> Option<f32> {
    let legs_in = || legs.iter().filter(|l| l.weight > 0.0 && l.gap.is_finite());
    let (lo, hi) = legs_in().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), l| {
        (lo.min(l.gap), hi.max(l.gap))
    });
    if !(lo <= hi) {
        return None;
    }
    let clamp = |h: f32| crate::bounds::clamp_safe(h, -limit, limit);
    let (lo, hi) = (clamp(lo), clamp(hi));
    if hi - lo <= 1e-6 || legs_in().count() == 1 {
        return Some(clamp(0.5 * (lo + hi)));
    }
    // Every leg's own cost falls towards its gap: the best height lies between the gaps.
    let shortest = legs_in().fold(f32::INFINITY, |s, l| s.min(l.length));
    let tol = HEIGHT_TOL_PER_LEG * shortest;
    let mut prepared = [Prepared::default(); MAX_FEET];
    for (p, l) in prepared.iter_mut().zip(legs) {
        *p = l.prepared(up);
    }
    let prepared = &prepared[..legs.len().min(MAX_FEET)];
    let cost = |h: f32| total(prepared, up, h);
    Some(least_within(cost, (lo, hi), SCAN, tol, MAX_STEPS))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 0.9 m leg (0.45 + 0.45) standing under a hip at 1 m, its knee bent `bend` degrees,
    /// its foot `gap` under where it must stand.
    fn leg(bend: f32, gap: f32, weight: f32) -> LegReach {
        let half = 0.5 * bend.to_radians();
        let (a, h) = (0.45f32, 0.45 * half.cos());
        let hip = Vec3::new(0.0, 1.0, 0.0);
        let knee = hip + Vec3::new(0.0, -h, a * half.sin());
        LegReach {
            hip,
            knee,
            ankle: hip - Vec3::new(0.0, 2.0 * h, 0.0),
            pole: Vec3::Z,
            gap,
            aside: Vec3::ZERO,
            weight,
            length: 0.9,
        }
    }

    #[test]
    fn one_leg_is_met_exactly_and_none_asks_nothing() {
        let up = Vec3::Y;
        let h = best_height(&[leg(30.0, 0.03, 1.0)], up, 0.2).unwrap();
        assert!((h - 0.03).abs() < 1e-6, "{h}");
        assert_eq!(best_height(&[leg(30.0, 0.03, 0.0)], up, 0.2), None);
        // Bounded.
        let h = best_height(&[leg(30.0, 0.5, 1.0)], up, 0.2).unwrap();
        assert!((h - 0.2).abs() < 1e-6, "{h}");
    }

    #[test]
    fn the_straighter_leg_keeps_its_height_the_bent_one_takes_the_difference() {
        let up = Vec3::Y;
        // A nearly straight leg wanting the body 4 cm down (its foot pinned 4 cm under the
        // animation's), a leg bent 40° wanting it where it is.
        let (straight, bent) = (leg(5.0, -0.04, 1.0), leg(40.0, 0.0, 1.0));
        let h = best_height(&[straight, bent], up, 0.2).unwrap();
        assert!(h < -0.03, "{h}: the mean would be -0.02");
        // The turns are smaller than the mean height's.
        let cost = |h: f32| total(&[straight.prepared(up), bent.prepared(up)], up, h);
        assert!(cost(h) < cost(-0.02), "{} vs {}", cost(h), cost(-0.02));
        // Either way round.
        let h = best_height(&[leg(40.0, -0.04, 1.0), leg(5.0, 0.0, 1.0)], up, 0.2).unwrap();
        assert!(h > -0.01, "{h}");
        // Two alike (bent well within their reach) share it about evenly.
        let h = best_height(&[leg(40.0, -0.02, 1.0), leg(40.0, 0.0, 1.0)], up, 0.2).unwrap();
        assert!((h + 0.01).abs() < 2e-3, "{h}");
    }

    #[test]
    fn a_goal_ahead_or_behind_stiffens_the_leg() {
        let up = Vec3::Y;
        // Two legs bent alike, one wanting the body 2 cm down; with that leg's pin also 15 cm
        // ahead of its ankle it reaches farther, nearer straight: it keeps more of its height.
        let (a, b) = (leg(40.0, -0.02, 1.0), leg(40.0, 0.0, 1.0));
        let below = best_height(&[a, b], up, 0.2).unwrap();
        let ahead = LegReach {
            aside: Vec3::new(0.15, 0.0, 0.0),
            ..a
        };
        let reaching = best_height(&[ahead, b], up, 0.2).unwrap();
        assert!(reaching < below - 0.002, "{reaching} vs {below}");
    }

    #[test]
    fn a_lighter_leg_counts_less() {
        let up = Vec3::Y;
        let full = best_height(&[leg(40.0, -0.02, 1.0), leg(40.0, 0.0, 1.0)], up, 0.2).unwrap();
        let light = best_height(&[leg(40.0, -0.02, 1.0), leg(40.0, 0.0, 0.2)], up, 0.2).unwrap();
        assert!(light < full - 0.005, "{light} vs {full}");
    }

    /// A leg of `thigh` + `shin` metres under a hip at 1 m, its knee bent `bend` degrees
    /// forward (+Z), its ankle's goal `gap` up and `aside` over the ground from it.
    fn leg_of(thigh: f32, shin: f32, bend: f32, gap: f32, aside: Vec3, weight: f32) -> LegReach {
        // The knee's bend `bend` from straight: the hip–ankle line vertical, the knee forward.
        let k = (180.0 - bend).to_radians();
        let d = (thigh * thigh + shin * shin - 2.0 * thigh * shin * k.cos()).sqrt();
        let cos_hip = (thigh * thigh + d * d - shin * shin) / (2.0 * thigh * d);
        let hip = Vec3::new(0.0, 1.0, 0.0);
        let knee =
            hip + thigh * Vec3::new(0.0, -cos_hip, (1.0 - cos_hip * cos_hip).max(0.0).sqrt());
        LegReach {
            hip,
            knee,
            ankle: hip - Vec3::new(0.0, d, 0.0),
            pole: Vec3::Z,
            gap,
            aside,
            weight,
            length: thigh + shin,
        }
    }

    /// The least of `cost` over `[lo, hi]` by brute force: `n` samples, then `n` more over
    /// the best one's neighbours (only a valley narrower than the first spacing, 0.07 mm
    /// below, could be missed).
    fn dense_least(cost: impl Fn(f32) -> f32, lo: f32, hi: f32, n: usize) -> f32 {
        let least = |lo: f32, hi: f32| {
            let at = |k: usize| lo + (hi - lo) * k as f32 / (n - 1) as f32;
            let best = (0..n).min_by(|&i, &j| cost(at(i)).total_cmp(&cost(at(j))));
            (at(best.unwrap_or(0)), (hi - lo) / (n - 1) as f32)
        };
        let (h, step) = least(lo, hi);
        least((h - step).max(lo), (h + step).min(hi)).0
    }

    /// Local minima of `cost` over `n` samples of `[lo, hi]`: valleys whose walls rise more
    /// than `rise` either side.
    fn valleys(cost: impl Fn(f32) -> f32, lo: f32, hi: f32, n: usize, rise: f32) -> usize {
        let at = |k: usize| lo + (hi - lo) * k as f32 / (n - 1) as f32;
        let (mut count, mut falling, mut low, mut high) = (0, true, cost(lo), cost(lo));
        for k in 1..n {
            let c = cost(at(k));
            if falling {
                low = low.min(c);
                if c > low + rise {
                    (count, falling, high) = (count + 1, false, c);
                }
            } else {
                high = high.max(c);
                if c < high - rise {
                    (falling, low) = (true, c);
                }
            }
        }
        count + usize::from(falling)
    }

    /// Awkward leg pairs (thighs 0.5-2 times their shins, legs at full stretch beside bent
    /// ones, goals ahead, behind and aside, light landing legs, two valleys): the height found
    /// costs what a brute-force search's least costs, save where the scan's 9 samples miss a
    /// narrow deeper valley (3 of 400; the golden-section search it replaced missed the same).
    #[test]
    fn the_height_turns_the_legs_as_a_dense_searchs_does() {
        let up = Vec3::Y;
        let mut seed = 12345u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut off, mut two, mut worst) = (0, 0, 0.0f32);
        let pairs = 400;
        for _ in 0..pairs {
            let mut mk = || {
                let (thigh, shin) = (0.3 + 0.3 * rnd(), 0.3 + 0.3 * rnd());
                let bend = [0.5, 2.0, 5.0, 15.0, 40.0, 80.0][(rnd() * 6.0) as usize % 6];
                let gap = -0.08 + 0.14 * rnd();
                let aside = Vec3::new(-0.2 + 0.4 * rnd(), 0.0, -0.1 + 0.2 * rnd());
                let aside = if rnd() < 0.3 { Vec3::ZERO } else { aside };
                let weight = if rnd() < 0.5 { 1.0 } else { 0.1 + 0.9 * rnd() };
                leg_of(thigh, shin, bend, gap, aside, weight)
            };
            let legs = [mk(), mk()];
            let (lo, hi) = (legs[0].gap.min(legs[1].gap), legs[0].gap.max(legs[1].gap));
            let prepared = legs.map(|l| l.prepared(up));
            let cost = |h: f32| total(&prepared, up, h);
            let dense = dense_least(cost, lo, hi, 2001);
            let h = best_height(&legs, up, 0.3).unwrap();
            two += usize::from(valleys(cost, lo, hi, 2001, 1e-4) > 1);
            let apart = prepared.iter().flat_map(|l| {
                let (a, b) = (l.turns(up, h), l.turns(up, dense));
                [(a[0] - b[0]).abs(), (a[1] - b[1]).abs()]
            });
            let apart = apart.fold(0.0f32, f32::max).to_degrees();
            let over = cost(h) - cost(dense);
            if over > 1e-4 {
                // A deeper valley between two of the scan's samples.
                off += 1;
                continue;
            }
            // Within 1e-5 rad² of the least (a tolerance of 1e-5 legs gives 1.9e-5 here, at
            // a leg at full stretch) and each bone within 0.15° (where the summed cost is
            // flat to its last bit over a tenth of a millimetre, two legs trade turns).
            assert!(over < 1e-5, "{h} vs {dense}: {over:e} rad² more");
            assert!(apart < 0.15, "{h} vs {dense}: a bone {apart}° apart");
            worst = worst.max(apart);
        }
        println!("{off} of {pairs} in another valley, {two} with two; worst otherwise {worst}°");
        assert!(
            two >= pairs / 20,
            "{two}: too few pairs with two valleys to test"
        );
        assert!(
            off * 100 <= pairs,
            "{off} of {pairs} off the dense search's valley"
        );
    }
}
