//! The BlazePose person detector (MediaPipe's `pose_detection`, converted to ONNX by
//! `scripts/setup-vision.sh`): finds people in the whole frame so the tracker knows where to
//! crop, instead of running the landmark model over a grid of guesses.
//!
//! The frame is letterboxed into the model's 224×224 input (values in [-1, 1]). The model
//! scores 2254 fixed anchors (SSD layout: 28², 14² and 7² cells with 2, 2 and 6 anchors each)
//! and regresses, per anchor, a box and four keypoints relative to the anchor's centre;
//! keypoint 0 is the hip centre and keypoint 1 a point that, with it, gives a circle around
//! the whole body — the same alignment pair as the landmark model's auxiliary points 33/34,
//! so a detection becomes a landmark ROI through [`Roi::from_alignment`]. Overlapping
//! detections of one person are merged by score-weighted non-maximum suppression.
//! Buffers (input tensor, candidates, output) are allocated in [`PersonDetector::load`].

use std::path::{Path, PathBuf};

use glam::Vec2;
use ort::session::Session;
use ort::value::Tensor;

use super::bound::BoundRun;
use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::sigmoid;
use super::model::{open_model, warp_crop, InputLayout};
use super::roi::Roi;

/// Side of the detector's square input, pixels.
pub const DETECTOR_SIZE: usize = 224;
/// Anchors the model scores.
pub const NUM_ANCHORS: usize = 2254;
const NUM_COORDS: usize = 12;
/// Raw logits are clipped here before the sigmoid (as MediaPipe does).
const SCORE_CLIP: f32 = 100.0;
/// Boxes overlapping more than this (intersection over union) are one person.
const NMS_IOU: f32 = 0.3;
/// At most this many people are reported per frame.
pub const MAX_DETECTIONS: usize = 8;

const OUT_BOXES: &str = "Identity";
const OUT_SCORES: &str = "Identity_1";

/// One person found in a frame, in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Confidence in [0, 1].
    pub score: f32,
    /// Box centre (the box is the face's: the detector finds faces and infers the body).
    pub center: Vec2,
    /// Box width and height.
    pub size: Vec2,
    /// Hip centre (keypoint 0).
    pub hip_center: Vec2,
    /// The body-circle point (keypoint 1).
    pub body_scale: Vec2,
}

impl Detection {
    /// The landmark model's crop for this person.
    pub fn roi(&self) -> Option<Roi> {
        Roi::from_alignment(self.hip_center, self.body_scale)
    }

    /// Radius of the circle around the whole body: how large the person appears.
    pub fn body_radius(&self) -> f32 {
        self.hip_center.distance(self.body_scale)
    }

    /// Intersection over union of the two (face) boxes.
    pub fn iou(&self, other: &Detection) -> f32 {
        box_iou(self.center, self.size, other.center, other.size)
    }

    fn blend(&mut self, other: &Detection, weight: f32) {
        self.center += other.center * weight;
        self.size += other.size * weight;
        self.hip_center += other.hip_center * weight;
        self.body_scale += other.body_scale * weight;
    }

    fn scaled(&self, k: f32) -> Detection {
        Detection {
            score: self.score,
            center: self.center * k,
            size: self.size * k,
            hip_center: self.hip_center * k,
            body_scale: self.body_scale * k,
        }
    }
}

/// Intersection over union of two axis-aligned boxes given as centre and size.
pub fn box_iou(ca: Vec2, sa: Vec2, cb: Vec2, sb: Vec2) -> f32 {
    let lo = (ca - sa * 0.5).max(cb - sb * 0.5);
    let hi = (ca + sa * 0.5).min(cb + sb * 0.5);
    let inter = (hi - lo).max(Vec2::ZERO);
    let inter = inter.x * inter.y;
    let union = sa.x * sa.y + sb.x * sb.y - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

/// Anchor centres in [0, 1]² in the model's output order (MediaPipe's SSD anchor options for
/// pose detection: strides 8, 16, 32, 32, 32, two anchors per layer, fixed size).
pub fn anchors() -> Vec<Vec2> {
    let mut out = Vec::with_capacity(NUM_ANCHORS);
    for (stride, per_cell) in [(8usize, 2usize), (16, 2), (32, 6)] {
        let cells = DETECTOR_SIZE.div_ceil(stride);
        for y in 0..cells {
            for x in 0..cells {
                let c = Vec2::new(
                    (x as f32 + 0.5) / cells as f32,
                    (y as f32 + 0.5) / cells as f32,
                );
                out.extend(std::iter::repeat_n(c, per_cell));
            }
        }
    }
    out
}

/// The detector and its buffers.
pub struct PersonDetector {
    path: PathBuf,
    session: Session,
    /// Boxes and scores, written in place by each run.
    run: BoundRun<2>,
    input: Tensor<f32>,
    layout: InputLayout,
    anchors: Vec<Vec2>,
    min_score: f32,
    candidates: Vec<Detection>,
}

debug_fields!(PersonDetector { path, min_score });

impl PersonDetector {
    /// Loads the detector `model` with the runtime in `library` on `threads` threads;
    /// detections below `min_score` are dropped.
    pub fn load(
        library: &Path,
        model: &Path,
        threads: usize,
        min_score: f32,
    ) -> Result<PersonDetector, VisionError> {
        let (session, input, layout) = open_model(
            library,
            model,
            "person detector model",
            threads,
            DETECTOR_SIZE,
        )?;
        let run = BoundRun::new(
            &session,
            model,
            [OUT_BOXES, OUT_SCORES],
            [NUM_ANCHORS * NUM_COORDS, NUM_ANCHORS],
            1,
        )?;
        let mut detector = PersonDetector {
            path: model.to_path_buf(),
            session,
            run,
            input,
            layout,
            anchors: anchors(),
            min_score,
            candidates: Vec::with_capacity(NUM_ANCHORS),
        };
        // The first run sizes the session's arena (see `LandmarkModel::load`).
        detector.run.run(&mut detector.session, &detector.input)?;
        Ok(detector)
    }

    /// Finds the people in `frame`, best first, into `out` (cleared first; at most
    /// [`MAX_DETECTIONS`]). Coordinates are pixels of `frame`.
    pub fn detect(
        &mut self,
        frame: &RgbFrame,
        out: &mut Vec<Detection>,
    ) -> Result<(), VisionError> {
        let (w, h) = (frame.width as f32, frame.height as f32);
        let whole = Roi::square(Vec2::new(w / 2.0, h / 2.0), w.max(h));
        self.detect_in(frame, &whole, out)
    }

    /// [`Self::detect`] on the upright square `letterbox` of `frame` only (a closer look:
    /// people appear larger to the model than in the whole frame).
    pub fn detect_in(
        &mut self,
        frame: &RgbFrame,
        letterbox: &Roi,
        out: &mut Vec<Detection>,
    ) -> Result<(), VisionError> {
        out.clear();
        let letterbox = *letterbox;
        {
            let (_, data) = self.input.extract_tensor_mut();
            let (scale, offset) = (1.0 / 127.5, -1.0);
            warp_crop(
                frame,
                &letterbox,
                DETECTOR_SIZE,
                scale,
                offset,
                self.layout,
                data,
            );
        }
        self.run.run(&mut self.session, &self.input)?;
        // Lengths were checked against the model when the outputs were bound.
        decode_anchors(
            self.run.output(0),
            self.run.output(1),
            &self.anchors,
            self.min_score,
            &mut self.candidates,
        );
        weighted_nms(&mut self.candidates, out);
        // From letterbox units ([0, 1]² over the long side) to frame pixels.
        let origin = letterbox.center - Vec2::splat(letterbox.size / 2.0);
        for d in out.iter_mut() {
            let mut p = d.scaled(letterbox.size);
            p.center += origin;
            p.hip_center += origin;
            p.body_scale += origin;
            *d = p;
        }
        Ok(())
    }
}

/// Anchors scoring at least `min_score`, decoded to letterbox units, into `out`.
fn decode_anchors(
    boxes: &[f32],
    scores: &[f32],
    anchors: &[Vec2],
    min_score: f32,
    out: &mut Vec<Detection>,
) {
    out.clear();
    let inv = 1.0 / DETECTOR_SIZE as f32;
    for (i, anchor) in anchors.iter().enumerate() {
        let score = sigmoid(scores[i].clamp(-SCORE_CLIP, SCORE_CLIP));
        if score < min_score {
            continue;
        }
        let r = &boxes[i * NUM_COORDS..(i + 1) * NUM_COORDS];
        let at = |k: usize| *anchor + Vec2::new(r[k], r[k + 1]) * inv;
        out.push(Detection {
            score,
            center: at(0),
            size: Vec2::new(r[2], r[3]) * inv,
            hip_center: at(4),
            body_scale: at(6),
        });
    }
}

/// Score-weighted non-maximum suppression: the best remaining candidate and every one that
/// overlaps it become one detection (positions averaged by score, the best score kept).
/// Consumes `candidates`.
fn weighted_nms(candidates: &mut Vec<Detection>, out: &mut Vec<Detection>) {
    candidates.sort_unstable_by(|a, b| b.score.total_cmp(&a.score));
    while !candidates.is_empty() && out.len() < MAX_DETECTIONS {
        let best = candidates[0];
        let mut merged = Detection {
            score: best.score,
            center: Vec2::ZERO,
            size: Vec2::ZERO,
            hip_center: Vec2::ZERO,
            body_scale: Vec2::ZERO,
        };
        let mut total = 0.0;
        candidates.retain(|c| {
            if c.iou(&best) <= NMS_IOU {
                return true;
            }
            merged.blend(c, c.score);
            total += c.score;
            false
        });
        // `scaled` keeps the score: the best one's.
        out.push(merged.scaled(1.0 / total));
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn anchor_layout_matches_the_model() {
        let a = anchors();
        assert_eq!(a.len(), NUM_ANCHORS);
        // First cell of the stride-8 layer, twice; last anchor is the last 7×7 cell.
        assert_eq!(a[0], Vec2::new(0.5 / 28.0, 0.5 / 28.0));
        assert_eq!(a[1], a[0]);
        assert_eq!(a[NUM_ANCHORS - 1], Vec2::new(6.5 / 7.0, 6.5 / 7.0));
        assert_eq!(a[28 * 28 * 2], Vec2::new(0.5 / 14.0, 0.5 / 14.0));
    }

    fn det(score: f32, x: f32) -> Detection {
        Detection {
            score,
            center: Vec2::new(x, 0.5),
            size: Vec2::splat(0.2),
            hip_center: Vec2::new(x, 0.55),
            body_scale: Vec2::new(x, 0.35),
        }
    }

    #[test]
    fn overlapping_candidates_merge_and_separate_people_stay_apart() {
        let mut c = vec![det(0.6, 0.30), det(0.9, 0.32), det(0.8, 0.70)];
        let mut out = Vec::new();
        weighted_nms(&mut c, &mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].score, 0.9);
        // Weighted towards the better one: (0.9·0.32 + 0.6·0.30) / 1.5.
        assert!(
            (out[0].center.x - 0.312).abs() < 1e-5,
            "{}",
            out[0].center.x
        );
        assert!((out[1].center.x - 0.70).abs() < 1e-6);
    }

    #[test]
    fn decoding_offsets_from_the_anchor_in_input_pixels() {
        let anchors = vec![Vec2::new(0.25, 0.75)];
        let mut boxes = [0.0f32; NUM_COORDS];
        boxes[0] = 22.4; // +0.1 in x
        boxes[2] = 44.8; // width 0.2
        boxes[3] = 112.0; // height 0.5
        boxes[7] = -22.4; // keypoint 1 is 0.1 above the anchor
        let mut out = Vec::new();
        decode_anchors(&boxes, &[3.0], &anchors, 0.5, &mut out);
        assert_eq!(out.len(), 1);
        let d = out[0];
        assert!((d.center - Vec2::new(0.35, 0.75)).length() < 1e-6);
        assert!((d.size - Vec2::new(0.2, 0.5)).length() < 1e-6);
        assert!((d.body_scale - Vec2::new(0.25, 0.65)).length() < 1e-6);
        decode_anchors(&boxes, &[-3.0], &anchors, 0.5, &mut out);
        assert!(out.is_empty());
    }
}
