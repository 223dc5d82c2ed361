//! Constant limb lengths for world landmarks.
//!
//! The model estimates each frame on its own, so a forearm can be 22 cm in one frame and 30 cm
//! in the next (foreshortening, occlusion). Bones do not stretch: this stage keeps a running,
//! visibility-weighted estimate of each limb segment's length and rebuilds the limb outwards
//! from the shoulders and hips, keeping every measured direction and replacing only lengths.
//!
//! A segment and its mirror twin share one estimate: limbs are the same length on both sides
//! to within a centimetre or two, and an arm hidden behind the body for most of a clip (its
//! joints guessed at low visibility) would otherwise keep a poorly measured length that drifts
//! whenever it is glimpsed, while the other arm is seen well all along.
//!
//! A settled estimate doubts lengths far from it: the model can misread a limb for dozens of
//! frames in a row at full visibility (a foreshortened arm behind another body), and a plain
//! running mean would follow it there.

use glam::Vec3;

use super::landmarks::{idx, Landmarks};

/// Limb segments (parent joint, child joint), ordered root-outwards so a parent is placed
/// before its children.
const SEGMENTS: [(usize, usize); 18] = [
    (idx::LEFT_SHOULDER, idx::LEFT_ELBOW),
    (idx::LEFT_ELBOW, idx::LEFT_WRIST),
    (idx::LEFT_WRIST, idx::LEFT_PINKY),
    (idx::LEFT_WRIST, idx::LEFT_INDEX),
    (idx::LEFT_WRIST, 21),
    (idx::RIGHT_SHOULDER, idx::RIGHT_ELBOW),
    (idx::RIGHT_ELBOW, idx::RIGHT_WRIST),
    (idx::RIGHT_WRIST, idx::RIGHT_PINKY),
    (idx::RIGHT_WRIST, idx::RIGHT_INDEX),
    (idx::RIGHT_WRIST, 22),
    (idx::LEFT_HIP, idx::LEFT_KNEE),
    (idx::LEFT_KNEE, idx::LEFT_ANKLE),
    (idx::LEFT_ANKLE, idx::LEFT_HEEL),
    (idx::LEFT_ANKLE, idx::LEFT_FOOT_INDEX),
    (idx::RIGHT_HIP, idx::RIGHT_KNEE),
    (idx::RIGHT_KNEE, idx::RIGHT_ANKLE),
    (idx::RIGHT_ANKLE, idx::RIGHT_HEEL),
    (idx::RIGHT_ANKLE, idx::RIGHT_FOOT_INDEX),
];

/// The shared estimate of each segment of [`SEGMENTS`]: a left segment and its right twin
/// (same place in the list of their side) use the same one.
const ESTIMATE_OF: [usize; SEGMENTS.len()] = [0, 1, 2, 3, 4, 0, 1, 2, 3, 4, 5, 6, 7, 8, 5, 6, 7, 8];
/// Number of shared estimates.
const ESTIMATES: usize = 9;

/// Cap on the accumulated weight: the estimate averages over roughly this many well-seen
/// frames, so it settles within a second or two yet still adapts to a new performer.
const MAX_WEIGHT: f32 = 90.0;

/// Accumulated weight from which an estimate is trusted enough to doubt measurements far
/// from it (about ten well-seen frames of both twins).
const SETTLED_WEIGHT: f32 = 20.0;
/// Relative length error at which a measurement counts half.
const LENGTH_SPREAD: f32 = 0.15;

/// Running limb-length estimates.
#[derive(Debug, Clone)]
pub struct LimbLengths {
    length: [f32; ESTIMATES],
    weight: [f32; ESTIMATES],
    measured: [Vec3; 33],
}

impl Default for LimbLengths {
    fn default() -> Self {
        LimbLengths::new()
    }
}

impl LimbLengths {
    /// No estimates yet.
    pub fn new() -> LimbLengths {
        LimbLengths {
            length: [0.0; ESTIMATES],
            weight: [0.0; ESTIMATES],
            measured: [Vec3::ZERO; 33],
        }
    }

    /// Forgets the estimates (a new person may appear after a loss).
    pub fn reset(&mut self) {
        self.length = [0.0; ESTIMATES];
        self.weight = [0.0; ESTIMATES];
    }

    /// Current estimate of segment `i` (metres), 0 before any observation.
    pub fn length(&self, i: usize) -> f32 {
        ESTIMATE_OF.get(i).map_or(0.0, |&k| self.length[k])
    }

    /// How much a measurement `len` of estimate `k` is believed, 1 for one near the estimate:
    /// once the estimate rests on enough frames ([`SETTLED_WEIGHT`]), a length far from it
    /// counts less the farther it is (a Cauchy weight of the relative error, scale
    /// [`LENGTH_SPREAD`]). The model can be confidently wrong for many frames in a row — an
    /// upper arm pointing at the camera from behind a body read at half its length at full
    /// visibility — and a plain running mean would follow it.
    fn plausibility(&self, k: usize, len: f32) -> f32 {
        if self.weight[k] < SETTLED_WEIGHT || self.length[k] <= 0.0 {
            return 1.0;
        }
        let relative = (len - self.length[k]) / (self.length[k] * LENGTH_SPREAD);
        1.0 / (1.0 + relative * relative)
    }

    /// Updates the estimates from `lm` and rewrites its limb world landmarks to those lengths.
    pub fn apply(&mut self, lm: &mut Landmarks) {
        self.measured.copy_from_slice(&lm.world[..33]);
        for (i, &(a, b)) in SEGMENTS.iter().enumerate() {
            let len = self.measured[a].distance(self.measured[b]);
            // Both ends must be seen for the measurement to count; a floor keeps the first
            // frames from being ignored entirely.
            let k = ESTIMATE_OF[i];
            let w = lm.visibility(a).min(lm.visibility(b)).max(0.05) * self.plausibility(k, len);
            if len.is_finite() && len > 0.0 {
                self.weight[k] = (self.weight[k] + w).min(MAX_WEIGHT);
                self.length[k] += (len - self.length[k]) * (w / self.weight[k]);
            }
            let dir = (self.measured[b] - self.measured[a]).normalize_or_zero();
            if dir != Vec3::ZERO && self.length[k] > 0.0 {
                lm.world[b] = lm.world[a] + dir * self.length[k];
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use glam::Vec4;

    fn arm(upper: f32, visible: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        for v in lm.image.iter_mut() {
            *v = Vec4::new(0.0, 0.0, 0.0, visible);
        }
        lm.world[idx::LEFT_SHOULDER] = Vec3::new(0.2, -0.5, 0.0);
        lm.world[idx::LEFT_ELBOW] = Vec3::new(0.2 + upper, -0.5, 0.0);
        lm.world[idx::LEFT_WRIST] = Vec3::new(0.2 + upper, -0.5 + 0.25, 0.0);
        lm
    }

    #[test]
    fn lengths_converge_to_the_average_and_directions_are_kept() {
        let mut f = LimbLengths::new();
        for i in 0..60 {
            let mut lm = arm(if i % 2 == 0 { 0.26 } else { 0.30 }, 1.0);
            f.apply(&mut lm);
        }
        assert!((f.length(0) - 0.28).abs() < 0.005, "{}", f.length(0));
        let mut lm = arm(0.34, 1.0);
        f.apply(&mut lm);
        let upper = lm.world[idx::LEFT_ELBOW] - lm.world[idx::LEFT_SHOULDER];
        assert!((upper.length() - 0.28).abs() < 0.01);
        assert!(upper.normalize_or_zero().abs_diff_eq(Vec3::X, 1e-5));
        // The forearm moved with the elbow and kept its own length and direction.
        let fore = lm.world[idx::LEFT_WRIST] - lm.world[idx::LEFT_ELBOW];
        assert!((fore.length() - 0.25).abs() < 1e-4);
    }

    #[test]
    fn each_shared_estimate_pairs_a_segment_with_its_mirror_twin() {
        // BlazePose numbers a body landmark's left twin odd and its right twin the next even
        // one (11/12 shoulders … 31/32 feet).
        let mirror = |i: usize| if i % 2 == 1 { i + 1 } else { i - 1 };
        for (i, &(a, b)) in SEGMENTS.iter().enumerate() {
            let twins: Vec<usize> = (0..SEGMENTS.len())
                .filter(|&j| j != i && ESTIMATE_OF[j] == ESTIMATE_OF[i])
                .collect();
            assert_eq!(
                twins.len(),
                1,
                "segment {i} shares its estimate with {twins:?}"
            );
            let (c, d) = SEGMENTS[twins[0]];
            assert_eq!(
                (mirror(a), mirror(b)),
                (c, d),
                "segment {i} and {}",
                twins[0]
            );
        }
        assert_eq!(ESTIMATE_OF.iter().max().map(|m| m + 1), Some(ESTIMATES));
    }

    #[test]
    fn a_hidden_arm_takes_the_length_of_the_arm_that_is_seen() {
        let mut f = LimbLengths::new();
        for i in 0..60 {
            let mut lm = arm(0.28, 1.0);
            // The right arm, barely visible, is guessed at lengths that jump about.
            for v in [idx::RIGHT_SHOULDER, idx::RIGHT_ELBOW] {
                lm.image[v].w = 0.05;
            }
            lm.world[idx::RIGHT_SHOULDER] = Vec3::new(-0.2, -0.5, 0.0);
            let guess = if i % 2 == 0 { 0.15 } else { 0.40 };
            lm.world[idx::RIGHT_ELBOW] = Vec3::new(-0.2 - guess, -0.5, 0.0);
            f.apply(&mut lm);
            if i >= 10 {
                let right = lm.world[idx::RIGHT_ELBOW] - lm.world[idx::RIGHT_SHOULDER];
                assert!((right.length() - 0.28).abs() < 0.02, "frame {i}: {right}");
                assert!(right.normalize_or_zero().abs_diff_eq(-Vec3::X, 1e-5));
            }
        }
        assert_eq!(
            f.length(0),
            f.length(5),
            "left and right upper arm share one estimate"
        );
    }

    #[test]
    fn a_long_run_of_confidently_wrong_lengths_barely_moves_a_settled_estimate() {
        let mut f = LimbLengths::new();
        for _ in 0..30 {
            f.apply(&mut arm(0.28, 1.0));
        }
        // Camera 3 of the pose2sim clip: the man's upper arm, pointing at the camera from
        // behind his body, read at 0.05–0.2 m with visibility above 0.9 for 40 frames.
        for _ in 0..40 {
            f.apply(&mut arm(0.12, 1.0));
        }
        assert!((f.length(0) - 0.28).abs() < 0.02, "{}", f.length(0));
        // Lengths near the estimate still move it, at the running mean's pace.
        for _ in 0..200 {
            f.apply(&mut arm(0.30, 1.0));
        }
        assert!((f.length(0) - 0.30).abs() < 0.005, "{}", f.length(0));
    }

    #[test]
    fn poorly_seen_frames_barely_move_the_estimate() {
        let mut f = LimbLengths::new();
        for _ in 0..30 {
            f.apply(&mut arm(0.28, 1.0));
        }
        for _ in 0..10 {
            f.apply(&mut arm(0.10, 0.05));
        }
        assert!((f.length(0) - 0.28).abs() < 0.01, "{}", f.length(0));
    }
}
