//! The whole per-frame path: frame → tracker (landmarks) → [`LandmarkStages`] (One Euro
//! smoothing → constant limb lengths → solver) → pose.

use std::sync::Arc;

use rigcast_retarget::{Pose, Skeleton};

use super::assets::{ModelKind, VisionAssets};
use super::detector::PersonDetector;
use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::Landmarks;
use super::model::{InputRange, LandmarkModel};
use super::solve::SolverConfig;
use super::stages::LandmarkStages;
use super::tracker::{Finder, PoseTracker, TrackerConfig, TrackerStats};

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

/// Frame → landmarks → rotations of the BlazePose skeleton, for each tracked person.
/// Allocates only when built.
#[derive(Debug)]
pub struct PosePipeline {
    tracker: PoseTracker,
    people: Vec<Person>,
    /// Time the last frame spent in the model-free stages (smoothing, lengths, solving).
    solve_time: std::time::Duration,
    /// The landmark model it runs.
    model: ModelKind,
}

/// One identity slot's stages and outputs.
#[derive(Debug)]
struct Person {
    stages: LandmarkStages,
    /// The tracker's landmarks in source pixels (before smoothing).
    raw: Landmarks,
    pose: Pose,
    seen: bool,
}

impl PosePipeline {
    /// Loads the runtime, the landmark model, (for [`Finder::Detector`]) the person detector
    /// and the second-opinion landmark model named by `config`.
    pub fn new(config: &PipelineConfig) -> Result<PosePipeline, VisionError> {
        let assets = &config.assets;
        let library = assets.require(assets.runtime_library(), "ONNX Runtime shared library")?;
        let model_path = assets.require(assets.landmark_model(config.model), "landmark model")?;
        let mut model = LandmarkModel::load(
            &library,
            &model_path,
            config.threads,
            config.tracker.max_people,
        )?;
        model.set_input_range(config.input_range);
        let detector = match config.tracker.finder {
            Finder::Detector => {
                let path = assets.require(assets.detector_model(), "person detector model")?;
                Some(PersonDetector::load(
                    &library,
                    &path,
                    config.threads,
                    config.tracker.min_detection_score,
                )?)
            }
            Finder::Search => None,
        };
        let mut tracker = PoseTracker::new(model, detector, config.tracker);
        let second = config.tracker.second_opinion;
        // A second opinion on left and right where the model's readings are in doubt (see
        // `TrackerConfig::second_opinion`): another model than the pipeline's, for the guard.
        if let Some(kind) = second.filter(|&k| k != config.model && config.tracker.swap_guard) {
            let path =
                assets.require(assets.landmark_model(kind), "second-opinion landmark model")?;
            let mut second = LandmarkModel::load(&library, &path, config.threads, 1)?;
            second.set_input_range(config.input_range);
            tracker.set_second_opinion(second);
        }
        let mut people = Vec::with_capacity(tracker.max_people());
        for _ in 0..tracker.max_people() {
            let stages = config.stages()?;
            let pose = stages.skeleton().rest_pose();
            people.push(Person {
                stages,
                raw: Landmarks::default(),
                pose,
                seen: false,
            });
        }
        Ok(PosePipeline {
            tracker,
            people,
            solve_time: std::time::Duration::ZERO,
            model: config.model,
        })
    }

    /// The BlazePose source skeleton poses are written for.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        self.people[0].stages.skeleton()
    }

    /// The landmark model it runs.
    pub fn model(&self) -> ModelKind {
        self.model
    }

    /// Tracker counters.
    pub fn stats(&self) -> TrackerStats {
        self.tracker.stats()
    }

    /// Identity slots (`#0` … `#num_people-1`).
    pub fn num_people(&self) -> usize {
        self.people.len()
    }

    /// Per-bone confidence of person `#0`'s last solved frame.
    pub fn confidence(&self) -> &[f32] {
        self.people[0].stages.confidence()
    }

    /// The tracker (e.g. to switch the model's input range).
    pub fn tracker_mut(&mut self) -> &mut PoseTracker {
        &mut self.tracker
    }

    /// Processes one frame for everyone: afterwards [`Self::person`], [`Self::pose`] and
    /// [`Self::raw_person`] tell each slot's result. A slot not seen in this frame keeps its
    /// last pose (the caller holds it).
    pub fn process_frame(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        self.track_frame(frame)?;
        self.find_people(frame)?;
        Ok(())
    }

    /// The first half of [`Self::process_frame`]: the people already tracked, landmarks to
    /// poses. Afterwards [`Self::person`] and [`Self::pose`] tell their results, ready to be
    /// published before [`Self::find_people`] (which must follow on the same frame) runs the
    /// finder.
    pub fn track_frame(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        self.tracker.track(frame)?;
        self.solve_time = std::time::Duration::ZERO;
        for person in self.people.iter_mut() {
            person.seen = false;
        }
        self.solve_seen(frame);
        Ok(())
    }

    /// The second half of [`Self::process_frame`]: the finder when it is due. Returns whether
    /// it found anyone (they are seen in this frame, their poses solved); every slot still
    /// unseen is then lost for this frame.
    pub fn find_people(&mut self, frame: &RgbFrame) -> Result<bool, VisionError> {
        self.tracker.find(frame)?;
        let found = self.solve_seen(frame);
        for person in self.people.iter_mut().filter(|p| !p.seen) {
            person.stages.lost();
        }
        Ok(found)
    }

    /// Solves every slot the tracker saw in this frame that is not solved yet; returns whether
    /// there was any.
    fn solve_seen(&mut self, frame: &RgbFrame) -> bool {
        let solving = std::time::Instant::now();
        let mut any = false;
        for (slot, person) in self.people.iter_mut().enumerate() {
            let Some(tracked) = self.tracker.person(slot).filter(|_| !person.seen) else {
                continue;
            };
            person.raw = *tracked;
            person.raw.picture = glam::Vec2::new(frame.width as f32, frame.height as f32);
            person.raw.scale_image(frame.source_from_frame);
            person.raw.take_refinement();
            person
                .stages
                .process(&person.raw, frame.time_secs, &mut person.pose);
            person.seen = true;
            any = true;
        }
        self.solve_time += solving.elapsed();
        any
    }

    /// Time the last frame spent after the model: smoothing, limb lengths, solving (both
    /// halves).
    pub fn solve_time(&self) -> std::time::Duration {
        self.solve_time
    }

    /// Smoothed landmarks (source pixels) of person `slot` in the last frame, if seen.
    pub fn person(&self, slot: usize) -> Option<&Landmarks> {
        let p = self.people.get(slot).filter(|p| p.seen)?;
        Some(p.stages.smoothed())
    }

    /// Raw landmarks (source pixels, before smoothing) of person `slot`, if seen in the last
    /// frame: what the raw tap records.
    pub fn raw_person(&self, slot: usize) -> Option<&Landmarks> {
        self.people.get(slot).filter(|p| p.seen).map(|p| &p.raw)
    }

    /// The pose of person `slot` (the last solved one, held while not seen).
    pub fn pose(&self, slot: usize) -> Option<&Pose> {
        self.people.get(slot).map(|p| &p.pose)
    }

    /// Processes one frame. With person `#0` in view, returns their (smoothed) landmarks and
    /// writes their solved pose into `pose` (sized for [`Self::skeleton`]); with none, returns
    /// `None` and leaves `pose` unchanged (the caller holds the last pose).
    pub fn process(
        &mut self,
        frame: &RgbFrame,
        pose: &mut Pose,
    ) -> Result<Option<&Landmarks>, VisionError> {
        self.process_frame(frame)?;
        let person = &self.people[0];
        if !person.seen {
            return Ok(None);
        }
        if pose.num_bones() == person.pose.num_bones() {
            pose.copy_from(&person.pose);
        } else {
            pose.clone_from(&person.pose);
        }
        Ok(Some(person.stages.smoothed()))
    }

    /// Raw (unsmoothed) landmarks of person `#0`'s last frame with a person: what the raw tap
    /// records and [`super::LandmarkReplaySource`] feeds back through the same stages.
    pub fn raw_landmarks(&self) -> &Landmarks {
        &self.people[0].raw
    }
}
