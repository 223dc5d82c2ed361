//! Constant limb lengths for world landmarks.
//!
//! The model estimates each frame on its own, so a forearm can be 22 cm in one frame and 30 cm
//! in the next (foreshortening, occlusion). Bones do not stretch: this stage keeps a running,
//! visibility-weighted estimate of each limb segment's length and rebuilds the limb outwards
//! from the shoulders and hips, keeping every measured direction and replacing only lengths.

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

/// Cap on the accumulated weight: the estimate averages over roughly this many well-seen
/// frames, so it settles within a second or two yet still adapts to a new performer.
const MAX_WEIGHT: f32 = 90.0;

/// Running limb-length estimates.
#[derive(Debug, Clone)]
pub struct LimbLengths {
    length: [f32; SEGMENTS.len()],
    weight: [f32; SEGMENTS.len()],
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
            length: [0.0; SEGMENTS.len()],
            weight: [0.0; SEGMENTS.len()],
            measured: [Vec3::ZERO; 33],
        }
    }

    /// Forgets the estimates (a new person may appear after a loss).
    pub fn reset(&mut self) {
        self.length = [0.0; SEGMENTS.len()];
        self.weight = [0.0; SEGMENTS.len()];
    }

    /// Current estimate of segment `i` (metres), 0 before any observation.
    pub fn length(&self, i: usize) -> f32 {
        self.length[i]
    }

    /// Updates the estimates from `lm` and rewrites its limb world landmarks to those lengths.
    pub fn apply(&mut self, lm: &mut Landmarks) {
        self.measured.copy_from_slice(&lm.world[..33]);
        for (i, &(a, b)) in SEGMENTS.iter().enumerate() {
            let len = self.measured[a].distance(self.measured[b]);
            // Both ends must be seen for the measurement to count; a floor keeps the first
            // frames from being ignored entirely.
            let w = lm.visibility(a).min(lm.visibility(b)).max(0.05);
            if len.is_finite() && len > 0.0 {
                self.weight[i] = (self.weight[i] + w).min(MAX_WEIGHT);
                self.length[i] += (len - self.length[i]) * (w / self.weight[i]);
            }
            let dir = (self.measured[b] - self.measured[a]).normalize_or_zero();
            if dir != Vec3::ZERO && self.length[i] > 0.0 {
                lm.world[b] = lm.world[a] + dir * self.length[i];
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
