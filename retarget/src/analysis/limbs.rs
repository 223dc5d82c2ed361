//! Splitting one limb chain into clavicle | upper | lower | extremity | digits.
//!
//! Straight rest poses (T-pose arms) give no elbow angle, so the split is chosen by bone
//! lengths: the upper and lower segments are the two dominant consecutive groups and their
//! ratio is close to the anatomical one; a group may hold several bones (Rigify's `.001`
//! segments, in-chain twist bones) at a small cost; the extremity is short compared with the
//! lower segment. This is what puts the wrist on the wrist when an arm has 6 bones and the
//! other 4 (seed 000's failure): the fingertip cannot be a forearm-sized segment.

/// Where a chain splits. Indices into the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ChainSplit {
    /// First bone of the upper segment (bones before it are clavicle / pelvis helpers).
    pub upper: usize,
    /// First bone of the lower segment.
    pub lower: usize,
    /// The extremity (hand / foot) bone.
    pub extremity: usize,
    /// Fit cost (0 is perfect); confidence is derived from it.
    pub cost: f32,
}

/// `lengths[i]` is the length of chain bone `i`; `bent[i]` is what grouping bones `i - 1` and
/// `i` into one segment costs because the joint between them bends (missing entries: 0); `fixed_extremity` is set when a branch
/// point (fingers, toes) already tells where the hand / foot is; `ratio` is the expected
/// upper / lower length ratio; `start[a]` is what starting the upper segment at chain bone `a`
/// costs (a leg's first bone that spans the girdle, an arm's joint nearer the midline than a
/// shoulder sits, see `extremities`; missing entries: 0).
#[cfg(test)]
pub(crate) fn fit_chain(
    lengths: &[f32],
    bent: &[f32],
    fixed_extremity: Option<usize>,
    ratio: f32,
    start: &[f32],
) -> Option<ChainSplit> {
    best_split(&chain_splits(lengths, bent, fixed_extremity, ratio, start))
}

/// The cheapest of `splits`, the first on ties.
pub(crate) fn best_split(splits: &[ChainSplit]) -> Option<ChainSplit> {
    let mut best: Option<ChainSplit> = None;
    for &cand in splits {
        if best.is_none_or(|b| cand.cost < b.cost - 1e-6) {
            best = Some(cand);
        }
    }
    best
}

/// The splits [`fit_chain`] weighs (same arguments) that cost at most `NEAR_SPLIT` more than
/// the cheapest, with their costs: the cheapest and its close rivals.
pub(crate) fn chain_splits(
    lengths: &[f32],
    bent: &[f32],
    fixed_extremity: Option<usize>,
    ratio: f32,
    start: &[f32],
) -> Vec<ChainSplit> {
    let m = lengths.len();
    let mut out: Vec<ChainSplit> = Vec::new();
    if m < 2 {
        return out;
    }
    let costs = SplitCosts::new(lengths, bent, ratio, start);
    let mut cheapest = f32::INFINITY;
    // Up to three bones before the upper segment: a helper at the spine's joint, the clavicle
    // and a scapula (MakeHuman's `__Clavicle` with a scapula between clavicle and arm).
    let max_pre = 3.min(m.saturating_sub(2));
    for a in 0..=max_pre {
        for b in (a + 1)..m {
            // The extremity may be missing when the chain ends at the lower segment.
            let extremities = match fixed_extremity {
                Some(e) => e..=e,
                None => (b + 1)..=m,
            };
            for e in extremities.filter(|&e| e > b && e <= m) {
                let Some(cost) = costs.of(a, b, e) else {
                    continue;
                };
                if cost <= cheapest + NEAR_SPLIT {
                    cheapest = cheapest.min(cost);
                    let (upper, lower, extremity) = (a, b, e);
                    out.push(ChainSplit {
                        upper,
                        lower,
                        extremity,
                        cost,
                    });
                }
            }
        }
    }
    out.retain(|s| s.cost <= cheapest + NEAR_SPLIT);
    out
}

/// What a split of one chain costs: [`chain_splits`]'s arguments, and the terms it adds up.
/// Each term adds to the running cost in a fixed order (the sum's rounding is part of which
/// split wins a near tie).
struct SplitCosts<'a> {
    lengths: &'a [f32],
    bent: &'a [f32],
    ratio: f32,
    start: &'a [f32],
    /// The chain is a leg's (its expected ratio is near 1).
    leg: bool,
    /// A leg's first bone seen to span the girdle.
    girdle_first: bool,
}

impl<'a> SplitCosts<'a> {
    fn new(lengths: &'a [f32], bent: &'a [f32], ratio: f32, start: &'a [f32]) -> Self {
        let leg = ratio < 1.1;
        let mut costs = SplitCosts {
            lengths,
            bent,
            ratio,
            start,
            leg,
            girdle_first: false,
        };
        costs.girdle_first = leg && costs.start_cost(0) > 0.0;
        costs
    }

    fn start_cost(&self, a: usize) -> f32 {
        self.start.get(a).copied().unwrap_or(0.0)
    }

    fn bent(&self, i: usize) -> f32 {
        self.bent.get(i).copied().unwrap_or(0.0)
    }

    /// The cost of the upper segment from bone `a`, the lower from `b`, the extremity at `e`
    /// (`e == m`: none); `None` when a segment has no length.
    fn of(&self, a: usize, b: usize, e: usize) -> Option<f32> {
        let m = self.lengths.len();
        let upper: f32 = self.lengths[a..b].iter().sum();
        let mut lower: f32 = self.lengths[b..e].iter().sum();
        let mut cost = 0.0;
        // A chain ending in a lone leaf at the lower segment (glTF rigs without hands or
        // feet): the leaf's length is unknown, not zero. Assume the expected ratio, at a
        // price, so that the upper segment is still found.
        if lower <= 1e-6 && e == m && b == m - 1 && self.lone_leaf_fits(a, b) && upper > 1e-6 {
            lower = upper / self.ratio;
            cost += 0.4;
        }
        if upper <= 1e-6 || lower <= 1e-6 {
            return None;
        }
        self.add_segments(&mut cost, (a, b, e), upper, lower);
        cost += self.start_cost(a);
        if a > 0 {
            self.add_before_upper(&mut cost, a, upper);
        }
        self.add_extremity(&mut cost, e, upper, lower);
        Some(cost.max(0.0))
    }

    /// Whether the lower segment may be a lone leaf of unknown length: a leg has no girdle
    /// bone before it unless its first bone spans one, and the upper segment may hold several
    /// bones only when the leaf is seen to turn (a twist bone splitting it above a glTF
    /// forearm).
    fn lone_leaf_fits(&self, a: usize, b: usize) -> bool {
        let lone = if self.leg {
            a <= usize::from(self.girdle_first)
        } else {
            a <= 1
        };
        let grouped_ok = b == a + 1 || self.bent(b) >= MOTION_BEND;
        grouped_ok && lone
    }

    /// The segments' proportion, their grouped bones and where they bend.
    fn add_segments(
        &self,
        cost: &mut f32,
        (a, b, e): (usize, usize, usize),
        upper: f32,
        lower: f32,
    ) {
        // Saturating: robots and cartoons have wild proportions, and past a point the bends
        // and the clavicle's size must still be able to decide.
        let d2 = ((upper / lower).ln() - self.ratio.ln()).powi(2);
        *cost += 4.0 * d2 / (1.0 + 2.0 * d2);
        // Extra bones in a group (segments / twist bones) are allowed but not free. Dearer
        // than a long hand (Xsens measures the hand to the fingertips, ≈0.75 of the forearm),
        // so a hand is not folded into the forearm to shorten it.
        *cost += 0.2 * ((b - a - 1) + (e - b - 1)) as f32;
        // Segments of one anatomical bone are collinear; a bent joint splits groups.
        *cost += (a + 1..b)
            .chain(b + 1..e)
            .map(|i| self.bent(i))
            .sum::<f32>();
        // A leg's bones before the thigh (a pelvis side, helpers) do not bend against each
        // other: a joint there that bends is the knee (a cartoon's short thigh and shin read
        // as pelvis bones before a long foot). A shoulder's do (a clavicle after a clavicle
        // helper).
        if self.leg {
            *cost += (1..a).map(|i| self.bent(i)).sum::<f32>();
        }
        // The elbow or knee bends: where the limb's joints (upper segment to extremity) are
        // seen to bend in the motion, a lower segment starting at one that never does is not
        // the limb's (an in-chain twist bone read as the forearm).
        let flexes = |i: usize| self.bent(i) >= MOTION_BEND;
        if !flexes(b) && (a + 1..=e.min(self.lengths.len() - 1)).any(flexes) {
            *cost += STIFF_ELBOW_COST;
        }
    }

    /// The bones before the upper segment (`a > 0`): the clavicle is the last of them;
    /// helpers before it (MakeHuman's `__Clavicle`) do not make it longer.
    fn add_before_upper(&self, cost: &mut f32, a: usize, upper: f32) {
        let pre: f32 = self.lengths[a - 1];
        // ...but a long bone before it is a limb segment, not a helper.
        for &l in &self.lengths[..a - 1] {
            *cost += 4.0 * (l / upper - 0.5).max(0.0);
        }
        // A clavicle is shorter than the upper segment; legs rarely have one.
        let (limit, k) = if self.leg { (0.45, 4.0) } else { (0.8, 2.0) };
        // ...unless it is seen to span the girdle, whatever its size (wide hips over a
        // robot's short thighs).
        if !(a == 1 && self.girdle_first) {
            *cost += k * (pre / upper - limit).max(0.0);
        }
        *cost += 0.02 * a as f32;
    }

    /// The extremity against the lower segment, and what follows it against the limb.
    fn add_extremity(&self, cost: &mut f32, e: usize, upper: f32, lower: f32) {
        if e == self.lengths.len() {
            *cost += 0.3;
            return;
        }
        // Saturating too: a cartoon's big feet on short legs.
        let sat = |c: f32| c / (1.0 + 0.5 * c);
        let ext = self.lengths[e];
        *cost += sat(2.0 * (ext / lower - 0.6).max(0.0));
        let rest: f32 = self.lengths[e..].iter().sum();
        *cost += sat(2.0 * (rest / (upper + lower) - 0.7).max(0.0));
    }
}

/// What `bent` gives a joint seen to bend in the motion (see `extremities`).
pub(crate) const MOTION_BEND: f32 = 3.0;

/// What starting the lower segment at a joint that never bends costs a split, while another
/// joint of the chain bends in the motion: as much as a bend seen at rest.
const STIFF_ELBOW_COST: f32 = 1.0;

/// How much dearer than the cheapest a split [`chain_splits`] keeps may be: a reading e^3
/// (20) times less likely is no rival.
pub(crate) const NEAR_SPLIT: f32 = 3.0;

/// What a split makes of chain bone `i`: before the upper segment, the upper segment's first
/// bone or a later one, the lower segment's likewise, the extremity, or past it.
fn part_of(s: &ChainSplit, i: usize) -> u8 {
    match i {
        _ if i < s.upper => 0,
        _ if i == s.upper => 1,
        _ if i < s.lower => 2,
        _ if i == s.lower => 3,
        _ if i < s.extremity => 4,
        _ if i == s.extremity => 5,
        _ => 6,
    }
}

/// Per chain bone (of `m`), how much dearer the cheapest of `splits` is that reads it otherwise
/// than `best` does (infinite when none does): the margin the bone's role won by.
pub(crate) fn split_margins(splits: &[ChainSplit], best: &ChainSplit, m: usize) -> Vec<f32> {
    let mut out = vec![f32::INFINITY; m];
    for s in splits {
        for (i, slot) in out.iter_mut().enumerate() {
            if part_of(s, i) != part_of(best, i) {
                *slot = slot.min(s.cost - best.cost);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit_chain_t(l: &[f32], fixed: Option<usize>, ratio: f32) -> Option<ChainSplit> {
        fit_chain(l, &[], fixed, ratio, &[])
    }

    #[test]
    fn mixamo_arm() {
        let s = fit_chain_t(&[0.12, 0.28, 0.25, 0.0], Some(3), 1.12).expect("fit");
        assert_eq!((s.upper, s.lower, s.extremity), (1, 2, 3));
    }

    #[test]
    fn six_bone_arm_puts_the_wrist_on_the_wrist() {
        let s = fit_chain_t(&[0.15, 0.3, 0.25, 0.09, 0.05, 0.0], None, 1.12).expect("fit");
        assert_eq!((s.upper, s.lower, s.extremity), (1, 2, 3));
        let s = fit_chain_t(&[0.15, 0.3, 0.25, 0.0], None, 1.12).expect("fit");
        assert_eq!((s.upper, s.lower, s.extremity), (1, 2, 3));
    }

    #[test]
    fn segmented_rigify_leg() {
        let s = fit_chain_t(&[0.225, 0.225, 0.21, 0.21, 0.14, 0.05, 0.0], None, 1.05).expect("fit");
        assert_eq!((s.upper, s.lower, s.extremity), (0, 2, 4));
    }

    /// A zero-length thigh helper whose segment spans the hips to a short thigh (Mousey's
    /// proportions): by lengths alone the girdle reads as the thigh; seen to span the girdle
    /// (what `extremities` measures), it is the pelvis side.
    #[test]
    fn a_bone_seen_to_span_the_girdle_is_not_the_thigh() {
        let l = [0.107, 0.13, 0.106, 0.103, 0.045, 0.0];
        let s = fit_chain(&l, &[], None, 1.05, &[]).expect("fit");
        assert_eq!(s.upper, 0);
        let s = fit_chain(&l, &[], None, 1.05, &[3.0]).expect("fit");
        assert_eq!((s.upper, s.lower, s.extremity), (1, 2, 3));
        // A wide girdle over a short thigh whose shin ends in a lone leaf (an IK foot beside).
        let s = fit_chain(&[0.66, 0.61, 0.0], &[], None, 1.05, &[3.0]).expect("fit");
        assert_eq!((s.upper, s.lower), (1, 2));
    }

    #[test]
    fn cmu_leg_with_hip_joint() {
        let s = fit_chain_t(&[0.13, 0.43, 0.44, 0.12, 0.0], None, 1.05).expect("fit");
        assert_eq!((s.upper, s.lower, s.extremity), (1, 2, 3));
    }
}
