//! The whole per-frame path: frame → tracker (landmarks) → One Euro smoothing → constant limb
//! lengths → solver (pose).

use std::sync::Arc;

use rigcast_retarget::{Pose, Skeleton};

use super::assets::{ModelKind, VisionAssets};
use super::body::blazepose_skeleton;
use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::{Landmarks, NUM_MODEL_LANDMARKS};
use super::lengths::LimbLengths;
use super::model::{InputRange, LandmarkModel};
use super::one_euro::{OneEuro, OneEuroParams};
use super::solve::{PoseSolver, SolverConfig};
use super::tracker::{PoseTracker, TrackerConfig, TrackerStats};

/// Everything needed to build a [`PosePipeline`].
#[derive(Debug, Clone)]
pub struct PipelineConfig {
    /// Where the runtime and models are.
    pub assets: VisionAssets,
    /// Which landmark model.
    pub model: ModelKind,
    /// Inference threads.
    pub threads: usize,
    /// Input scaling of the model.
    pub input_range: InputRange,
    /// Search/tracking settings.
    pub tracker: TrackerConfig,
    /// Rotation solving settings.
    pub solver: SolverConfig,
    /// One Euro smoothing of landmarks (off = raw model output).
    pub smoothing: bool,
    /// Hold limb lengths constant in the world landmarks.
    pub constant_lengths: bool,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        PipelineConfig {
            assets: VisionAssets::from_env(),
            model: ModelKind::Lite,
            threads: std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(2),
            input_range: InputRange::default(),
            tracker: TrackerConfig::default(),
            solver: SolverConfig::default(),
            smoothing: true,
            constant_lengths: true,
        }
    }
}

/// Frame → landmarks → rotations of the BlazePose skeleton. Allocates only when built.
#[derive(Debug)]
pub struct PosePipeline {
    tracker: PoseTracker,
    solver: PoseSolver,
    raw: Landmarks,
    smoothed: Landmarks,
    image_filters: [[OneEuro; 3]; NUM_MODEL_LANDMARKS],
    world_filters: [[OneEuro; 3]; NUM_MODEL_LANDMARKS],
    smoothing: bool,
    lengths: Option<LimbLengths>,
    tracking: bool,
}

impl PosePipeline {
    /// Loads the runtime and model named by `config`.
    pub fn new(config: &PipelineConfig) -> Result<PosePipeline, VisionError> {
        let assets = &config.assets;
        let library = assets.require(assets.runtime_library(), "ONNX Runtime shared library")?;
        let model_path = assets.require(assets.landmark_model(config.model), "landmark model")?;
        let mut model = LandmarkModel::load(&library, &model_path, config.threads)?;
        model.set_input_range(config.input_range);
        let skeleton = blazepose_skeleton()?;
        Ok(PosePipeline {
            tracker: PoseTracker::new(model, config.tracker),
            solver: PoseSolver::new(skeleton, config.solver),
            raw: Landmarks::default(),
            smoothed: Landmarks::default(),
            image_filters: [[OneEuro::new(OneEuroParams::PIXELS); 3]; NUM_MODEL_LANDMARKS],
            world_filters: [[OneEuro::new(OneEuroParams::METRES); 3]; NUM_MODEL_LANDMARKS],
            smoothing: config.smoothing,
            lengths: config.constant_lengths.then(LimbLengths::new),
            tracking: false,
        })
    }

    /// The BlazePose source skeleton poses are written for.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        self.solver.skeleton()
    }

    /// Tracker counters.
    pub fn stats(&self) -> TrackerStats {
        self.tracker.stats()
    }

    /// Per-bone confidence of the last solved frame.
    pub fn confidence(&self) -> &[f32] {
        self.solver.confidence()
    }

    /// The tracker (e.g. to switch the model's input range).
    pub fn tracker_mut(&mut self) -> &mut PoseTracker {
        &mut self.tracker
    }

    /// Processes one frame. With a person in view, returns the (smoothed) landmarks and writes
    /// the solved pose into `pose` (sized for [`Self::skeleton`]); with none, returns `None`
    /// and leaves `pose` unchanged (the caller holds the last pose).
    pub fn process(
        &mut self,
        frame: &RgbFrame,
        pose: &mut Pose,
    ) -> Result<Option<&Landmarks>, VisionError> {
        let found = self.tracker.process(frame, &mut self.raw)?;
        if !found {
            if self.tracking {
                self.reset_filters();
            }
            self.tracking = false;
            return Ok(None);
        }
        self.tracking = true;
        let t = frame.time_secs;
        self.smoothed = self.raw;
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
        Ok(Some(&self.smoothed))
    }

    /// Raw (unsmoothed) landmarks of the last frame with a person.
    pub fn raw_landmarks(&self) -> &Landmarks {
        &self.raw
    }

    fn reset_filters(&mut self) {
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
