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

/// Golden-section steps after the coarse scan (the bracket shrinks 0.618 a step: 24 steps
/// leave a 10⁻⁵ of it).
const REFINE_STEPS: usize = 24;

/// Coarse samples over the bracket (the cost of two legs need not have one minimum).
const SCAN: usize = 9;

impl LegReach {
    /// The squared turn of the leg's thigh and shin (radians², plus what it misses) with the
    /// body moved up by `h`.
    fn cost(&self, up: Vec3, h: f32) -> f32 {
        let shift = up * h;
        let (hip, knee, ankle) = (self.hip + shift, self.knee + shift, self.ankle + shift);
        let goal = self.ankle + self.aside + up * self.gap;
        // The bones' places alone, as the IK puts them: their rotations are not needed to
        // score them.
        let placed = Chain::new(hip, knee, ankle).and_then(|c| c.place(goal - hip, self.pole));
        let (to_knee, to_ankle) = placed.map_or((knee, ankle), |(k, a)| (hip + k, hip + a));
        let thigh = (knee - hip).angle_between(to_knee - hip);
        let shin = (ankle - knee).angle_between(to_ankle - to_knee);
        let miss = MISS_RAD_PER_LEG * (goal - to_ankle).length() / self.length.max(1e-6);
        let sq = |a: f32| if a.is_finite() { a * a } else { 0.0 };
        sq(thigh) + sq(shin) + sq(miss)
    }
}

fn total(legs: &[LegReach], up: Vec3, h: f32) -> f32 {
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
    let cost = |h: f32| total(legs, up, h);
    Some(super::search::least_between(
        cost,
        lo,
        hi,
        SCAN,
        REFINE_STEPS,
    ))
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
        let cost = |h: f32| straight.cost(up, h) + bent.cost(up, h);
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
}
