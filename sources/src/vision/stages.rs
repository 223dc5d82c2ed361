//! The model-free half of the vision pipeline: landmarks → One Euro smoothing → constant limb
//! lengths → rotations of the BlazePose skeleton.
//!
//! [`PosePipeline`](super::PosePipeline) runs these stages on the tracker's output for live
//! video; [`LandmarkReplaySource`](super::LandmarkReplaySource) runs the very same stages on
//! landmarks read back from a recording, so a replay reproduces the live poses without the
//! model or a camera.

use std::sync::Arc;

use rigcast_retarget::{Pose, Skeleton};

use super::body::blazepose_skeleton;
use super::error::VisionError;
use super::landmarks::{Landmarks, NUM_MODEL_LANDMARKS};
use super::lengths::LimbLengths;
use super::one_euro::{OneEuro, OneEuroParams};
use super::solve::{PoseSolver, SolverConfig};

/// Smoothing, constant lengths and solving for one tracked person. Allocates only in `new`.
#[derive(Debug)]
pub struct LandmarkStages {
    solver: PoseSolver,
    smoothed: Landmarks,
    image_filters: [[OneEuro; 3]; NUM_MODEL_LANDMARKS],
    world_filters: [[OneEuro; 3]; NUM_MODEL_LANDMARKS],
    smoothing: bool,
    lengths: Option<LimbLengths>,
    tracking: bool,
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
            smoothing,
            lengths: constant_lengths.then(LimbLengths::new),
            tracking: false,
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
        if let Some(lengths) = self.lengths.as_mut() {
            lengths.apply(&mut self.smoothed);
        }
        if pose.num_bones() != self.solver.skeleton().num_bones() {
            *pose = self.solver.skeleton().rest_pose();
        }
        self.solver.solve(&self.smoothed, t, pose);
        &self.smoothed
    }

    /// The person left the view: the next person starts fresh filters and length estimates
    /// (the solver keeps its output, so the caller holds the last pose).
    pub fn lost(&mut self) {
        if !self.tracking {
            return;
        }
        self.tracking = false;
        if let Some(lengths) = self.lengths.as_mut() {
            lengths.reset();
        }
        for f in self
            .image_filters
            .iter_mut()
            .chain(self.world_filters.iter_mut())
        {
            for c in f.iter_mut() {
                c.reset();
            }
        }
    }
}
