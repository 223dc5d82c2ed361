//! Live, a foot's learnt standing height held from one stance to the next
//! ([`Foot::take_stance`], [`Foot::end_stance`]): learnt over its first stance and held (the
//! performer's floor does not move, and pins that moved with each stance's own height stood
//! the feet higher or lower on each), unless that first stance turns out not to be the
//! performance's: a calibration pose held off the floor, a foot caught planted for a few
//! frames as the performance begins. Held from such a stance, the pins kept its height for
//! the whole performance. Stances do differ among themselves (live, in process, the pymo
//! Meredith walk onto the Bandai-Namco run rig: one foot's stances 5.4-7.4 cm, the other's
//! 2.4-7.5), so the first is judged against how much the later ones differ, their few
//! counted as few. Re-learnt at every stance two of its own spreads from the one held (the
//! ball's height held and re-learnt alike), the planted feet stood within 1 cm of the
//! performer's on 71 of 152 pairs instead of 97; judged against the later stances' spread
//! as if it were known (three standard deviations, not Student's t), the Meredith walk's
//! foot above was re-learnt after four stances, that pair's planted feet 0.98 -> 1.89 cm.

use super::*;

/// Later stances a first stance is judged against, at least.
pub(super) const LATER_STANCES: f32 = 3.0;

/// Student's t, two-sided 99 %, for 2 to 10 degrees of freedom: a stance from the same
/// spread as `n` others lies within `t · s · √(1 + 1/n)` of their mean 99 times in 100, `s`
/// their sample standard deviation with `n − 1` degrees of freedom.
const T99: [f32; 9] = [
    9.925, 5.841, 4.604, 4.032, 3.707, 3.499, 3.355, 3.250, 3.169,
];

/// [`T99`] for `dof` degrees of freedom (at least 2); past 10, approaching the normal
/// distribution's 2.576 (within 0.03 of the table's values).
fn t99(dof: f32) -> f32 {
    let d = dof.max(2.0);
    if d <= 10.0 {
        T99[(d.round() as usize) - 2]
    } else {
        2.576 + (T99[8] - 2.576) * 10.0 / d
    }
}

/// The weighted mean and spread of one height: over a stance's frames (each weighted by its
/// time), or over several stances' means (one each).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Moments {
    weight: f32,
    mean: f32,
    sq: f32,
}

impl Moments {
    /// Takes one more sample, `weight` of it, at `x`.
    pub(super) fn add(&mut self, x: f32, weight: f32) {
        if !(weight > 0.0) || !x.is_finite() {
            return;
        }
        self.weight += weight;
        let k = weight / self.weight;
        self.mean += k * (x - self.mean);
        self.sq += k * (x * x - self.sq);
    }

    /// Whether any sample was taken.
    pub(super) fn any(&self) -> bool {
        self.weight > 0.0
    }

    pub(super) fn mean(&self) -> f32 {
        self.mean
    }

    /// The (population) standard deviation of the samples about their mean.
    pub(super) fn spread(&self) -> f32 {
        (self.sq - self.mean * self.mean).max(0.0).sqrt()
    }

    /// Whether `first`'s mean lies outside where, 99 times in 100, one more stance would
    /// lie given these, the means of the stances after it, one each: their prediction
    /// interval ([`T99`]); not before [`LATER_STANCES`] of them.
    pub(super) fn leaves_out(&self, first: f32) -> bool {
        let n = self.weight;
        if !(n >= LATER_STANCES) {
            return false;
        }
        let sample = self.spread() * (n / (n - 1.0)).sqrt();
        let reach = t99(n - 1.0) * sample * (1.0 + 1.0 / n).sqrt();
        (first - self.mean).abs() > reach
    }
}

impl Foot {
    /// Takes one held stance frame, `dt` long, whose heel stands `heel` above the floor (as
    /// the lock rolls the foot) into this stance's height, and, over the first stance, into
    /// the height learnt ([`Foot::learn_height`]).
    pub(super) fn take_stance(&mut self, heel: f32, dt: f32) {
        if !self.heights_held {
            self.learn_height(heel, dt);
        }
        self.stance_heel.add(heel, dt);
    }

    /// The foot has lifted: the stance it stood is over. The first sets the height held
    /// ([`Foot::learn_height`] read it). Each later one counts towards how the later stances
    /// stand; once the first stands outside them ([`Moments::leaves_out`]), their mean height
    /// replaces its (as [`Foot::heel_from`] reads it), once: the first was no stance of the
    /// performance. The height moves only here, between stances, never under a pinned foot.
    pub(super) fn end_stance(&mut self) {
        if !(self.learns_heights && self.stance_heel.any()) {
            return;
        }
        let stance = std::mem::take(&mut self.stance_heel);
        if !self.heights_held {
            self.heights_held = true;
            self.first_heel = stance.mean();
            return;
        }
        if self.relearnt {
            return;
        }
        self.later_heel.add(stance.mean(), 1.0);
        if self.later_heel.leaves_out(self.first_heel) {
            let later = self.later_heel;
            self.heel_clearance = self.heel_from(later.mean(), later.spread());
            self.relearnt = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A foot learning its heights standing `secs` with its heel at `heel` (swaying by
    /// `sway` either way from frame to frame), then lifting, as [`FootLock::learn_fit`]
    /// drives it.
    fn stand(foot: &mut Foot, heel: f32, sway: f32, secs: f32) {
        let dt = 1.0 / 60.0;
        for k in 0..(secs / dt).round() as usize {
            let h = if k % 2 == 0 { heel + sway } else { heel - sway };
            foot.take_stance(h, dt);
        }
        foot.end_stance();
    }

    fn learning_foot() -> Foot {
        let leg = crate::footplant::lock::tests::left_leg(None, 0.9);
        let mut foot = Foot::unlocked_at(leg, Some(0), Vec3::ZERO);
        foot.learns_heights = true;
        foot
    }

    #[test]
    fn stances_that_differ_as_a_walks_do_keep_the_first_ones_height() {
        let mut foot = learning_foot();
        stand(&mut foot, 0.075, 0.005, 0.4);
        assert!((foot.heel_clearance - 0.075).abs() < 1e-4);
        // Later stances 1-2 cm lower, as the pymo Meredith walk's onto the Bandai run rig.
        for heel in [0.063, 0.064, 0.054, 0.058, 0.066, 0.056] {
            stand(&mut foot, heel, 0.005, 0.4);
            assert!(
                (foot.heel_clearance - 0.075).abs() < 1e-4,
                "{}",
                foot.heel_clearance
            );
        }
    }

    #[test]
    fn a_first_stance_unlike_the_later_ones_is_learnt_again_from_them() {
        let mut foot = learning_foot();
        // A calibration pose held 6 cm over the walk's stances, still.
        stand(&mut foot, 0.150, 0.001, 2.0);
        assert!((foot.heel_clearance - 0.150).abs() < 1e-4);
        // The walk: held at the pose's height until three stances tell the walk's apart,
        // then at their mean, and held there whatever comes later.
        let walk = [0.092, 0.088, 0.090, 0.094, 0.060, 0.150];
        for (k, heel) in walk.into_iter().enumerate() {
            stand(&mut foot, heel, 0.004, 0.5);
            let wanted = if k < 2 { 0.150 } else { 0.090 };
            assert!(
                (foot.heel_clearance - wanted).abs() < 1e-4,
                "{k}: {}",
                foot.heel_clearance
            );
        }
    }

    #[test]
    fn the_later_stances_spread_is_read_with_the_few_of_them_there_are() {
        // Three stances whose means spread 1 mm: a first one 1 cm off lies within their
        // 99 % prediction (t = 9.9 for two degrees of freedom: 1.2 cm), 2 cm off outside.
        let mut later = Moments::default();
        for m in [0.089, 0.090, 0.091] {
            later.add(m, 1.0);
        }
        assert!(!later.leaves_out(0.100));
        assert!(later.leaves_out(0.110));
        // Two are not enough to judge by.
        let mut two = Moments::default();
        two.add(0.090, 1.0);
        two.add(0.090, 1.0);
        assert!(!two.leaves_out(0.5));
    }
}
