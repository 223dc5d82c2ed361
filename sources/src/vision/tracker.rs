//! Finding and tracking one person: candidate-crop search to start or recover, ROI tracking
//! from the previous frame's auxiliary landmarks, and a guard against left/right label swaps.
//!
//! Why a search instead of MediaPipe's detector: the detector does not convert to ONNX as is.
//! The landmark model itself reports a pose presence, so running it over a handful of crops
//! (the whole frame letterboxed, centred squares, a coarse grid) and keeping the most present
//! one finds the person; one refinement pass with the ROI from that result's auxiliary
//! landmarks then centres and scales the crop. While presence stays above the threshold each
//! frame just reuses the previous ROI; when it drops, the next frame searches again.

use glam::{Vec2, Vec3};

use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::{idx, Landmarks};
use super::model::LandmarkModel;
use super::roi::Roi;

/// Tracker settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// Minimum pose presence for a result to count as a person.
    pub presence_threshold: f32,
    /// Refinement passes after a search hit (each one model run).
    pub refine_passes: usize,
    /// Undo the model's facing/away reading flips (left/right label swaps) by matching the
    /// torso against recent frames.
    pub swap_guard: bool,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            presence_threshold: 0.5,
            refine_passes: 2,
            swap_guard: true,
        }
    }
}

/// Left/right landmark pairs used by the swap guard (and swapped together).
const LR_PAIRS: [(usize, usize); 16] = [
    (1, 4),
    (2, 5),
    (3, 6),
    (7, 8),
    (9, 10),
    (11, 12),
    (13, 14),
    (15, 16),
    (17, 18),
    (19, 20),
    (21, 22),
    (23, 24),
    (25, 26),
    (27, 28),
    (29, 30),
    (31, 32),
];

/// Pairs whose positions decide whether the reading flipped: the torso corners, which move
/// least and are seen best (arms legitimately move a lot between frames).
const GUARD_PAIRS: [(usize, usize); 2] = [
    (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER),
    (idx::LEFT_HIP, idx::RIGHT_HIP),
];

/// How fast the flip guard's reference follows accepted frames (fraction per frame).
const REFERENCE_RATE: f32 = 0.3;

/// Counters for diagnostics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrackerStats {
    /// Model runs.
    pub inferences: u64,
    /// Candidate searches started.
    pub searches: u64,
    /// Left/right label swaps undone.
    pub swaps_fixed: u64,
}

/// Finds and tracks one person with a [`LandmarkModel`].
#[derive(Debug)]
pub struct PoseTracker {
    model: LandmarkModel,
    config: TrackerConfig,
    roi: Option<Roi>,
    candidates: Vec<Roi>,
    scratch: Landmarks,
    reference: Option<[Vec3; 2]>,
    stats: TrackerStats,
}

impl PoseTracker {
    /// A tracker with no person yet.
    pub fn new(model: LandmarkModel, config: TrackerConfig) -> PoseTracker {
        PoseTracker {
            model,
            config,
            roi: None,
            candidates: Vec::with_capacity(16),
            scratch: Landmarks::default(),
            reference: None,
            stats: TrackerStats::default(),
        }
    }

    /// The model (e.g. to change its input range).
    pub fn model_mut(&mut self) -> &mut LandmarkModel {
        &mut self.model
    }

    /// Counters since creation.
    pub fn stats(&self) -> TrackerStats {
        self.stats
    }

    /// The ROI that the next frame will use, if tracking.
    pub fn roi(&self) -> Option<Roi> {
        self.roi
    }

    /// Forgets the tracked person; the next frame searches.
    pub fn reset(&mut self) {
        self.roi = None;
        self.reference = None;
    }

    /// Processes one frame. Returns true and fills `out` when a person was found.
    pub fn process(&mut self, frame: &RgbFrame, out: &mut Landmarks) -> Result<bool, VisionError> {
        let threshold = self.config.presence_threshold;
        let mut found = false;
        if let Some(roi) = self.roi {
            self.model.infer(frame, &roi, out)?;
            self.stats.inferences += 1;
            found = out.presence >= threshold;
        }
        if !found {
            self.reference = None;
            found = self.search(frame, out)?;
        }
        if !found {
            self.roi = None;
            return Ok(false);
        }
        if let Some(reference) = self.reference.as_ref().filter(|_| self.config.swap_guard) {
            if labels_swapped(reference, out) {
                flip_interpretation(out);
                self.stats.swaps_fixed += 1;
            }
        }
        self.roi = next_roi(out);
        update_reference(&mut self.reference, out);
        Ok(true)
    }

    fn search(&mut self, frame: &RgbFrame, out: &mut Landmarks) -> Result<bool, VisionError> {
        self.stats.searches += 1;
        Roi::search_candidates(frame.width, frame.height, &mut self.candidates);
        let mut best_presence = -1.0;
        for i in 0..self.candidates.len() {
            let roi = self.candidates[i];
            self.model.infer(frame, &roi, &mut self.scratch)?;
            self.stats.inferences += 1;
            if self.scratch.presence > best_presence {
                best_presence = self.scratch.presence;
                *out = self.scratch;
            }
        }
        if best_presence < self.config.presence_threshold {
            return Ok(false);
        }
        // Re-crop around the person found; keep a refinement only if it is still a person.
        for _ in 0..self.config.refine_passes {
            let Some(roi) = next_roi(out) else { break };
            self.model.infer(frame, &roi, &mut self.scratch)?;
            self.stats.inferences += 1;
            if self.scratch.presence < self.config.presence_threshold {
                break;
            }
            *out = self.scratch;
        }
        Ok(true)
    }
}

fn next_roi(lm: &Landmarks) -> Option<Roi> {
    let c = lm.image[idx::AUX_CENTER];
    let s = lm.image[idx::AUX_SCALE];
    Roi::from_alignment(Vec2::new(c.x, c.y), Vec2::new(s.x, s.y))
}

/// Torso lines (left minus right, world) of hips and shoulders: what the flip guard compares.
fn torso_lines(lm: &Landmarks) -> [Vec3; 2] {
    GUARD_PAIRS.map(|(l, r)| lm.world[l] - lm.world[r])
}

/// The torso lines after [`flip_interpretation`]: left and right exchange (negating the line)
/// and depth is mirrored, so x and y change sign and z stays.
fn flipped_lines(lines: [Vec3; 2]) -> [Vec3; 2] {
    lines.map(|v| Vec3::new(-v.x, -v.y, v.z))
}

/// True when the current frame fits the reference better with its reading flipped.
///
/// Why: on ambiguous views (a blurred face, a side view) the model sometimes switches between
/// "facing the camera" and "facing away" — the two readings of the same image, one the other
/// mirrored in depth with left and right exchanged — often for single frames, sometimes
/// through a degenerate in-between frame. Comparing against a reference that follows the
/// accepted frames with some inertia (rather than against the last frame alone) keeps one
/// degenerate frame from deciding the labels of all that follow.
fn labels_swapped(reference: &[Vec3; 2], cur: &Landmarks) -> bool {
    let same = torso_lines(cur);
    let flipped = flipped_lines(same);
    let cost = |lines: &[Vec3; 2]| -> f32 {
        lines
            .iter()
            .zip(reference)
            .map(|(a, b)| a.distance(*b))
            .sum()
    };
    cost(&flipped) < cost(&same)
}

/// Moves the reference torso lines towards the accepted frame's.
fn update_reference(reference: &mut Option<[Vec3; 2]>, lm: &Landmarks) {
    let lines = torso_lines(lm);
    *reference = Some(match *reference {
        Some(r) => [
            r[0].lerp(lines[0], REFERENCE_RATE),
            r[1].lerp(lines[1], REFERENCE_RATE),
        ],
        None => lines,
    });
}

/// The other reading of the same image: depth mirrored, left and right labels exchanged.
/// (Two mirrors make a proper rotation, so the result is a valid body.)
fn flip_interpretation(lm: &mut Landmarks) {
    for p in lm.world.iter_mut() {
        p.z = -p.z;
    }
    for p in lm.image.iter_mut() {
        p.z = -p.z;
    }
    for &(l, r) in &LR_PAIRS {
        lm.image.swap(l, r);
        lm.world.swap(l, r);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use glam::Vec4;

    fn person(offset_x: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        for &(l, r) in &LR_PAIRS {
            let y = l as f32 * 10.0;
            lm.image[l] = Vec4::new(offset_x + 50.0, y, 0.0, 1.0);
            lm.image[r] = Vec4::new(offset_x - 50.0, y, 0.0, 1.0);
            lm.world[l] = Vec3::new(0.1 + offset_x * 1e-3, y * 1e-3, 0.0);
            lm.world[r] = Vec3::new(-0.1 + offset_x * 1e-3, y * 1e-3, 0.0);
        }
        lm
    }

    #[test]
    fn a_depth_flip_is_detected_and_undone() {
        let mut reference = None;
        update_reference(&mut reference, &person(0.0));
        let reference = reference.unwrap();
        let mut cur = person(3.0);
        assert!(!labels_swapped(&reference, &cur));
        flip_interpretation(&mut cur);
        assert!(labels_swapped(&reference, &cur));
        flip_interpretation(&mut cur);
        assert_eq!(cur, person(3.0));
    }

    #[test]
    fn a_flip_keeps_limb_lengths_and_mirrors_depth() {
        let mut lm = person(0.0);
        lm.world[idx::LEFT_ELBOW].z = 0.2;
        let before = lm.world[idx::LEFT_SHOULDER].distance(lm.world[idx::LEFT_ELBOW]);
        flip_interpretation(&mut lm);
        let after = lm.world[idx::RIGHT_SHOULDER].distance(lm.world[idx::RIGHT_ELBOW]);
        assert!((before - after).abs() < 1e-6);
        assert_eq!(lm.world[idx::RIGHT_ELBOW].z, -0.2);
    }
}
