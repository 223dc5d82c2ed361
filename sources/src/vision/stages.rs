//! The model-free half of the vision pipeline: landmarks → One Euro smoothing → the camera's
//! axes and the image's picture-plane shape (see [`super::perspective`]) → the world output's
//! own smoothing (see [`super::world_smoothing`]) → constant limb lengths → rotations of the
//! BlazePose skeleton. Where the landmarks' left/right labelling
//! changes between frames, the filters' histories change sides with it.
//!
//! [`PosePipeline`](super::PosePipeline) runs these stages on the tracker's output for live
//! video; [`LandmarkReplaySource`](super::LandmarkReplaySource) runs the very same stages on
//! landmarks read back from a recording, so a replay reproduces the live poses without the
//! model or a camera.

use std::sync::Arc;

use glam::Vec3;
use rigcast_retarget::{Pose, Skeleton};

use super::body::blazepose_skeleton;
use super::error::VisionError;
use super::landmarks::{Landmarks, NUM_MODEL_LANDMARKS};
use super::lengths::LimbLengths;
use super::one_euro::{OneEuro, OneEuroParams};
use super::perspective;
use super::sides::{lines_swapped, reading_weight, torso_lines, LR_PAIRS};
use super::solve::{PoseSolver, SolverConfig};
use super::world_smoothing::WorldSmoothing;

/// A person back in their slot within this long (seconds) keeps their limb-length estimates:
/// the tracker lost them for a frame or two (a crossing, a detector miss) and re-found the
/// same person. Starting the estimates afresh there would settle them on whatever the model
/// reads at that moment, often the very misreading that lost the track (camera 3 of the
/// two-person demo decoded at 480: the man's upper arm from 0.27 m to 0.18 m).
const KEEP_LENGTHS_SECS: f64 = 0.5;

/// Smoothing, constant lengths and solving for one tracked person. Allocates only in `new`.
#[derive(Debug)]
pub struct LandmarkStages {
    solver: PoseSolver,
    smoothed: Landmarks,
    image_filters: [[OneEuro; 3]; NUM_MODEL_LANDMARKS],
    world_filters: [[OneEuro; 3]; NUM_MODEL_LANDMARKS],
    /// The world output's smoothing, after the perspective stage.
    output_filters: WorldSmoothing,
    smoothing: bool,
    lengths: Option<LimbLengths>,
    tracking: bool,
    /// When the person was last processed (the lengths are kept across a short loss).
    last_seen_secs: Option<f64>,
    /// The torso lines (left minus right, world) of the last frame's landmarks, to see the
    /// labels exchanged between frames (see [`Self::follow_exchanged_sides`]).
    last_lines: Option<[Vec3; 2]>,
}

impl LandmarkStages {
    /// Stages with the given solver settings; `smoothing` enables the One Euro filters and
    /// `constant_lengths` the limb-length stage (see [`super::PipelineConfig`]).
    pub fn new(
        solver: SolverConfig,
        smoothing: bool,
        constant_lengths: bool,
    ) -> Result<LandmarkStages, VisionError> {
        Ok(LandmarkStages {
            solver: PoseSolver::new(blazepose_skeleton()?, solver),
            smoothed: Landmarks::default(),
            image_filters: [[OneEuro::new(OneEuroParams::PIXELS); 3]; NUM_MODEL_LANDMARKS],
            world_filters: [[OneEuro::new(OneEuroParams::METRES); 3]; NUM_MODEL_LANDMARKS],
            output_filters: WorldSmoothing::new(),
            smoothing,
            lengths: constant_lengths.then(LimbLengths::new),
            tracking: false,
            last_seen_secs: None,
            last_lines: None,
        })
    }

    /// The BlazePose source skeleton poses are written for.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        self.solver.skeleton()
    }

    /// Per-bone confidence of the last solved frame.
    pub fn confidence(&self) -> &[f32] {
        self.solver.confidence()
    }

    /// Landmarks of the last frame after smoothing and constant lengths.
    pub fn smoothed(&self) -> &Landmarks {
        &self.smoothed
    }

    /// Runs one frame's model landmarks `raw` (observed at `time_secs`) through the stages and
    /// writes the solved pose into `pose` (resized to [`Self::skeleton`] if needed).
    pub fn process(&mut self, raw: &Landmarks, time_secs: f64, pose: &mut Pose) -> &Landmarks {
        self.tracking = true;
        let t = time_secs;
        // Back after longer than a short loss (or time went back: a replay restarted): maybe
        // someone else, so the length estimates start afresh.
        let gap = self.last_seen_secs.map(|last| t - last);
        if gap.is_some_and(|g| !(0.0..=KEEP_LENGTHS_SECS).contains(&g)) {
            if let Some(lengths) = self.lengths.as_mut() {
                lengths.reset();
            }
        }
        self.last_seen_secs = Some(t);
        self.follow_exchanged_sides(raw);
        self.smoothed = *raw;
        if self.smoothing {
            for i in 0..NUM_MODEL_LANDMARKS {
                let img = &mut self.smoothed.image[i];
                let f = &mut self.image_filters[i];
                img.x = f[0].filter(img.x, t);
                img.y = f[1].filter(img.y, t);
                img.z = f[2].filter(img.z, t);
                let w = &mut self.smoothed.world[i];
                let f = &mut self.world_filters[i];
                w.x = f[0].filter(w.x, t);
                w.y = f[1].filter(w.y, t);
                w.z = f[2].filter(w.z, t);
            }
        }
        perspective::apply(&mut self.smoothed);
        if self.smoothing {
            self.output_filters.apply(&mut self.smoothed, t);
        }
        if let Some(lengths) = self.lengths.as_mut() {
            lengths.apply(&mut self.smoothed);
        }
        if pose.num_bones() != self.solver.skeleton().num_bones() {
            *pose = self.solver.skeleton().rest_pose();
        }
        self.solver.solve(&self.smoothed, t, pose);
        &self.smoothed
    }

    /// When `raw` is labelled the other way round from the last frame (the tracker's left/right
    /// guard took the model's labelling, or there is no guard and the model read the mirror
    /// image), moves each filter's history to the landmark that now names its point: left and
    /// right exchanged, depth mirrored, as the labels were. Filtered through, the exchange
    /// would draw every left point across the body to its right twin over several frames, and
    /// the output would show a body labelled neither way meanwhile (basketball practice: the
    /// player's back, taken from the model on frame 173, read side-on in the output until
    /// frame 176). Only a decisive reading is compared (a torso
    /// facing the camera or away from it, its parts agreeing), and only with the frame just
    /// before when that one was decisive too: at a side view both labellings put the torso
    /// along the line of sight, and either comparison is a toss-up (pose2sim cam01: the lite
    /// model's one edge-on frame, then a square one, read as an exchange), and across one a
    /// body turned to its back is a mirror of its front.
    fn follow_exchanged_sides(&mut self, raw: &Landmarks) {
        let lines = torso_lines(raw);
        let decisive = reading_weight(raw) > 0.0;
        let exchanged = decisive
            && self
                .last_lines
                .is_some_and(|last| lines_swapped(&last, lines));
        self.last_lines = decisive.then_some(lines);
        if !exchanged || !self.smoothing {
            return;
        }
        for &(l, r) in &LR_PAIRS {
            self.image_filters.swap(l, r);
            self.world_filters.swap(l, r);
        }
        for f in self
            .image_filters
            .iter_mut()
            .chain(self.world_filters.iter_mut())
        {
            f[2].negate();
        }
        self.output_filters.exchange_sides();
    }

    /// The person left the view: the next frame starts fresh filters, and fresh length
    /// estimates unless the person is back within [`KEEP_LENGTHS_SECS`] (the solver keeps its
    /// output, so the caller holds the last pose).
    pub fn lost(&mut self) {
        if !self.tracking {
            return;
        }
        self.tracking = false;
        self.last_lines = None;
        for f in self
            .image_filters
            .iter_mut()
            .chain(self.world_filters.iter_mut())
        {
            for c in f.iter_mut() {
                c.reset();
            }
        }
        self.output_filters.reset();
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::vision::landmarks::idx;
    use glam::{Vec3, Vec4};

    /// A fully visible body whose upper arms are `upper` metres long.
    fn body(upper: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        for v in lm.image.iter_mut() {
            *v = Vec4::new(0.0, 0.0, 0.0, 1.0);
        }
        for (i, w) in lm.world.iter_mut().enumerate() {
            *w = Vec3::new(0.01 * i as f32, -0.02 * i as f32, 0.0);
        }
        lm.world[idx::LEFT_SHOULDER] = Vec3::new(0.2, -0.5, 0.0);
        lm.world[idx::LEFT_ELBOW] = Vec3::new(0.2 + upper, -0.5, 0.0);
        // Its twin, which shares the estimate, alike.
        lm.world[idx::RIGHT_SHOULDER] = Vec3::new(-0.2, -0.5, 0.0);
        lm.world[idx::RIGHT_ELBOW] = Vec3::new(-0.2 - upper, -0.5, 0.0);
        lm
    }

    fn upper_arm(lm: &Landmarks) -> f32 {
        lm.world[idx::LEFT_SHOULDER].distance(lm.world[idx::LEFT_ELBOW])
    }

    /// Forty frames at 30 fps with 0.27 m upper arms, lost, back `gap` seconds after the last
    /// one reading them at 0.18 m: the upper arm shown on the first frame back.
    fn back_after(gap: f64) -> f32 {
        let mut stages = LandmarkStages::new(SolverConfig::default(), false, true).unwrap();
        let mut pose = stages.skeleton().rest_pose();
        let dt = 1.0 / 30.0;
        for i in 0..40 {
            stages.process(&body(0.27), i as f64 * dt, &mut pose);
        }
        stages.lost();
        let back = stages.process(&body(0.18), 39.0 * dt + gap, &mut pose);
        upper_arm(back)
    }

    #[test]
    fn a_person_back_after_a_short_loss_keeps_their_limb_lengths() {
        // Lost for one frame: the same person, misread as they are found again.
        let kept = back_after(2.0 / 30.0);
        assert!((kept - 0.27).abs() < 0.01, "{kept}");
        // Lost for two seconds: maybe someone else, measured afresh.
        let fresh = back_after(2.0);
        assert!((fresh - 0.18).abs() < 1e-4, "{fresh}");
        // Time going back (a replay restarted) starts afresh too.
        let restarted = back_after(-1.0);
        assert!((restarted - 0.18).abs() < 1e-4, "{restarted}");
    }

    /// A body square on to the camera (its left on the picture's right), its elbows `depth`
    /// metres towards the camera, in the picture at `(x, 500)`; every other point at the hips.
    fn facing_body(x: f32, depth: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        // (landmark, towards the body's left, height above the hips, depth)
        let points = [
            (idx::LEFT_SHOULDER, 0.18, 0.5, 0.0),
            (idx::RIGHT_SHOULDER, -0.18, 0.5, 0.0),
            (idx::LEFT_HIP, 0.1, 0.0, 0.0),
            (idx::RIGHT_HIP, -0.1, 0.0, 0.0),
            (idx::LEFT_EAR, 0.07, 0.7, 0.0),
            (idx::RIGHT_EAR, -0.07, 0.7, 0.0),
            (idx::LEFT_ELBOW, 0.3, 0.25, -depth),
            (idx::RIGHT_ELBOW, -0.3, 0.25, -depth),
        ];
        for (i, across, up, z) in points {
            lm.world[i] = Vec3::new(across, -up, z);
            lm.image[i] = Vec4::new(x + 400.0 * across, 500.0 - 400.0 * up, 0.0, 1.0);
        }
        lm
    }

    fn mirrored(mut lm: Landmarks) -> Landmarks {
        crate::vision::sides::flip_interpretation(&mut lm);
        lm
    }

    /// The smoothed left elbow (picture x, depth) after a second of `body`, then `next`.
    fn left_elbow_after(body: &Landmarks, next: &[Landmarks]) -> (f32, f32) {
        let mut stages = LandmarkStages::new(SolverConfig::default(), true, false).unwrap();
        let mut pose = stages.skeleton().rest_pose();
        let dt = 1.0 / 30.0;
        for i in 0..30 {
            stages.process(body, i as f64 * dt, &mut pose);
        }
        let mut out = Landmarks::default();
        for (i, lm) in next.iter().enumerate() {
            out = *stages.process(lm, (30 + i) as f64 * dt, &mut pose);
        }
        let e = idx::LEFT_ELBOW;
        (out.image[e].x, out.world[e].z)
    }

    #[test]
    fn labels_exchanged_between_frames_exchange_the_filters_histories() {
        let body = facing_body(500.0, 0.2);
        // The same picture labelled the other way round (the guard took the model's
        // labelling): the left elbow is the right one's point, its depth mirrored, at once.
        let (x, z) = left_elbow_after(&body, &[mirrored(body)]);
        let want = mirrored(body);
        assert!((x - want.image[idx::LEFT_ELBOW].x).abs() < 0.5, "{x}");
        assert!((z - want.world[idx::LEFT_ELBOW].z).abs() < 1e-3, "{z}");
        // Labelled alike and moved: smoothed as before, lagging behind the move.
        let moved = facing_body(560.0, 0.2);
        let (x, _) = left_elbow_after(&body, &[moved]);
        assert!(
            x > 500.0 + 400.0 * 0.3 && x < 560.0 + 400.0 * 0.3 - 5.0,
            "{x}"
        );
    }

    #[test]
    fn no_exchange_is_read_across_an_edge_on_frame() {
        // A frame read edge-on (its torso along the line of sight, no evidence), then the
        // body square on again: its torso lines against the edge-on ones say nothing, so the
        // filters go on smoothing the same labels.
        let body = facing_body(500.0, 0.2);
        // Edge-on, leaning a little towards the mirror reading: compared with it, the next
        // square frame would read as exchanged.
        let mut edge_on = body;
        for (l, r, half) in [
            (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER, 0.18),
            (idx::LEFT_HIP, idx::RIGHT_HIP, 0.1),
        ] {
            let y = edge_on.world[l].y;
            edge_on.world[l] = Vec3::new(-0.1 * half, y, -half);
            edge_on.world[r] = Vec3::new(0.1 * half, y, half);
        }
        assert_eq!(reading_weight(&edge_on), 0.0);
        assert!(lines_swapped(&torso_lines(&edge_on), torso_lines(&body)));
        let (_, z) = left_elbow_after(&body, &[edge_on, body]);
        assert!((z - body.world[idx::LEFT_ELBOW].z).abs() < 1e-3, "{z}");
    }
}
