//! Finding and tracking one person: candidate-crop search to start or recover, ROI tracking
//! from the previous frame's auxiliary landmarks, and a guard against left/right label swaps.
//!
//! Why a search instead of MediaPipe's detector: the detector does not convert to ONNX as is.
//! The landmark model itself reports a pose presence, so running it over a handful of crops
//! (the whole frame letterboxed, centred squares, a coarse grid) and keeping the most present
//! one finds the person; one refinement pass with the ROI from that result's auxiliary
//! landmarks then centres and scales the crop. While presence stays above the threshold each
//! frame just reuses the previous ROI; when it drops, the next frame searches again.

use glam::Vec2;

use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::{idx, Landmarks, NUM_LANDMARKS};
use super::model::LandmarkModel;
use super::roi::Roi;

/// Tracker settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// Minimum pose presence for a result to count as a person.
    pub presence_threshold: f32,
    /// Refinement passes after a search hit (each one model run).
    pub refine_passes: usize,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            presence_threshold: 0.5,
            refine_passes: 2,
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

/// Pairs whose positions decide whether labels swapped (the large joints).
const GUARD_PAIRS: [(usize, usize); 6] = [
    (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER),
    (idx::LEFT_ELBOW, idx::RIGHT_ELBOW),
    (idx::LEFT_HIP, idx::RIGHT_HIP),
    (idx::LEFT_KNEE, idx::RIGHT_KNEE),
    (idx::LEFT_ANKLE, idx::RIGHT_ANKLE),
    (idx::LEFT_WRIST, idx::RIGHT_WRIST),
];

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
    previous: Option<Landmarks>,
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
            previous: None,
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
        self.previous = None;
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
            self.previous = None;
            found = self.search(frame, out)?;
        }
        if !found {
            self.roi = None;
            return Ok(false);
        }
        if let Some(prev) = &self.previous {
            if labels_swapped(prev, out) {
                swap_sides(out);
                self.stats.swaps_fixed += 1;
            }
        }
        self.roi = next_roi(out);
        self.previous = Some(*out);
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

/// True when the current frame's left/right labels fit the previous frame much better swapped
/// (the model occasionally flips sides for one frame on ambiguous views).
fn labels_swapped(prev: &Landmarks, cur: &Landmarks) -> bool {
    let p = |lm: &Landmarks, i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let mut same = 0.0;
    let mut swapped = 0.0;
    for &(l, r) in &GUARD_PAIRS {
        same += p(cur, l).distance(p(prev, l)) + p(cur, r).distance(p(prev, r));
        swapped += p(cur, l).distance(p(prev, r)) + p(cur, r).distance(p(prev, l));
    }
    swapped < 0.5 * same
}

fn swap_sides(lm: &mut Landmarks) {
    for &(l, r) in &LR_PAIRS {
        debug_assert!(l < NUM_LANDMARKS && r < NUM_LANDMARKS);
        lm.image.swap(l, r);
        lm.world.swap(l, r);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec3, Vec4};

    fn person(offset_x: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        for &(l, r) in &LR_PAIRS {
            let y = l as f32 * 10.0;
            lm.image[l] = Vec4::new(offset_x + 50.0, y, 0.0, 1.0);
            lm.image[r] = Vec4::new(offset_x - 50.0, y, 0.0, 1.0);
            lm.world[l] = Vec3::new(0.1, 0.0, 0.0);
            lm.world[r] = Vec3::new(-0.1, 0.0, 0.0);
        }
        lm
    }

    #[test]
    fn a_one_frame_flip_is_detected_and_undone() {
        let prev = person(0.0);
        let mut cur = person(3.0);
        assert!(!labels_swapped(&prev, &cur));
        swap_sides(&mut cur);
        assert!(labels_swapped(&prev, &cur));
        swap_sides(&mut cur);
        assert_eq!(cur, person(3.0));
    }
}
