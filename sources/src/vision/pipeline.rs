//! The whole per-frame path: frame → tracker (landmarks) → [`LandmarkStages`] (One Euro
//! smoothing → constant limb lengths → solver) → pose.

use std::sync::Arc;

use rigcast_retarget::{Pose, Skeleton};

use super::assets::{ModelKind, VisionAssets};
use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::Landmarks;
use super::model::{InputRange, LandmarkModel};
use super::solve::SolverConfig;
use super::stages::LandmarkStages;
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

impl PipelineConfig {
    /// The model-free stages (smoothing, constant lengths, solver) these settings describe.
    pub fn stages(&self) -> Result<LandmarkStages, VisionError> {
        LandmarkStages::new(self.solver, self.smoothing, self.constant_lengths)
    }
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
    stages: LandmarkStages,
    raw: Landmarks,
}

impl PosePipeline {
    /// Loads the runtime and model named by `config`.
    pub fn new(config: &PipelineConfig) -> Result<PosePipeline, VisionError> {
        let assets = &config.assets;
        let library = assets.require(assets.runtime_library(), "ONNX Runtime shared library")?;
        let model_path = assets.require(assets.landmark_model(config.model), "landmark model")?;
        let mut model = LandmarkModel::load(&library, &model_path, config.threads)?;
        model.set_input_range(config.input_range);
        Ok(PosePipeline {
            tracker: PoseTracker::new(model, config.tracker),
            stages: config.stages()?,
            raw: Landmarks::default(),
        })
    }

    /// The BlazePose source skeleton poses are written for.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        self.stages.skeleton()
    }

    /// Tracker counters.
    pub fn stats(&self) -> TrackerStats {
        self.tracker.stats()
    }

    /// Per-bone confidence of the last solved frame.
    pub fn confidence(&self) -> &[f32] {
        self.stages.confidence()
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
            self.stages.lost();
            return Ok(None);
        }
        Ok(Some(self.stages.process(&self.raw, frame.time_secs, pose)))
    }

    /// Raw (unsmoothed) landmarks of the last frame with a person: what the raw tap records
    /// and [`super::LandmarkReplaySource`] feeds back through the same stages.
    pub fn raw_landmarks(&self) -> &Landmarks {
        &self.raw
    }
}
