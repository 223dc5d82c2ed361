//! Video and webcam subjects: every subject of one file or camera (`video:FILE#0`,
//! `video:FILE#1`, …) is one person of one shared pipeline, so the input is decoded and the
//! model run once per frame for all of them, not once per subject.
//!
//! ```text
//!  [[sources]] video FILE #0 ─┐                  (one per configuration, boot/load)
//!  [[sources]] video FILE #1 ─┴─▶ VisionInputs: FILE → SharedVision ─▶ PersonSource #0, #1
//! ```

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use anyhow::Context;
use rigcast_retarget::Skeleton;
use rigcast_sources::vision::{
    ffmpeg::DEFAULT_SEQUENCE_FPS, DecodeSize, FfmpegSource, FrameSource, ModelKind, PersonSource,
    PipelineConfig, PosePipeline, SharedVision, TrackerConfig,
};

/// What a vision subject watches.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(not(feature = "webcam"), allow(dead_code))]
pub(crate) enum VisionInput {
    /// A video file (canonical path when it resolves, so two spellings share).
    File(PathBuf),
    /// A camera by index.
    Webcam(u32),
}

impl VisionInput {
    /// The input of `path`.
    pub(crate) fn file(path: &Path) -> VisionInput {
        VisionInput::File(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()))
    }
}

impl std::fmt::Display for VisionInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            VisionInput::File(p) => write!(f, "video {}", p.display()),
            VisionInput::Webcam(i) => write!(f, "webcam {i}"),
        }
    }
}

/// One opened input and the people count and model it was opened with.
struct Opened {
    input: VisionInput,
    people: usize,
    model: ModelKind,
    shared: SharedVision,
}

/// How a vision input is processed: the people tracked and the landmark model (`None`: the
/// default, or what an earlier spec of the same input chose).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct VisionOptions {
    pub(crate) people: Option<usize>,
    pub(crate) model: Option<ModelKind>,
}

/// `model = "lite"` and the like, checked (`None` when absent).
pub(crate) fn parse_model(model: Option<&str>) -> Result<Option<ModelKind>, String> {
    model.map(str::parse::<ModelKind>).transpose()
}

/// The inputs opened so far while loading one configuration (shared by its source specs).
#[derive(Clone, Default)]
pub(crate) struct VisionInputs {
    opened: Arc<Mutex<Vec<Opened>>>,
}

impl VisionInputs {
    /// Person `person` (default 0) of `input`, opening the input with `open` if no earlier
    /// spec did. The options' people (default: the tracker's) and model (default: lite) must
    /// agree with earlier specs of the input. Blocks (decoder, model loading).
    pub(crate) fn person(
        &self,
        input: VisionInput,
        person: Option<usize>,
        options: VisionOptions,
        open: impl FnOnce() -> anyhow::Result<Box<dyn FrameSource>>,
        realtime: bool,
    ) -> anyhow::Result<(PersonSource, Arc<Skeleton>)> {
        let mut opened = self
            .opened
            .lock()
            .map_err(|_| anyhow::anyhow!("vision inputs poisoned"))?;
        let existing = opened.iter().position(|o| o.input == input);
        let people = options.people;
        if let Some(i) = existing {
            if let Some(m) = options.model.filter(|m| *m != opened[i].model) {
                anyhow::bail!(
                    "{input}: model = {} here, but an earlier source of the same input runs {}; \
                     give them all the same model",
                    m.as_str(),
                    opened[i].model.as_str()
                );
            }
        }
        let tracked = match existing {
            Some(i) => {
                if let Some(p) = people.filter(|p| *p != opened[i].people) {
                    anyhow::bail!(
                        "{input}: people = {p} here, but an earlier source of the same input \
                         tracks {}; give them all the same people",
                        opened[i].people
                    );
                }
                opened[i].people
            }
            None => people.unwrap_or(TrackerConfig::default().max_people),
        };
        let person = person.unwrap_or(0);
        // Checked before anything is opened: a typo must not cost a model load.
        if tracked == 0 {
            anyhow::bail!("{input}: people must be at least 1");
        }
        if person >= tracked {
            anyhow::bail!(
                "{input}: no person #{person}: only {tracked} people are tracked (#0..#{}); \
                 set people = {} in its [[sources]] entry to track more",
                tracked - 1,
                person + 1
            );
        }
        let index = match existing {
            Some(i) => i,
            None => {
                let model = options.model.unwrap_or_default();
                let frames = open()?;
                let shared = SharedVision::new(frames, pipeline(tracked, model)?, realtime);
                opened.push(Opened {
                    input: input.clone(),
                    people: tracked,
                    model,
                    shared,
                });
                opened.len() - 1
            }
        };
        let shared = &opened[index].shared;
        let source = shared.person(person, format!("{input}#{person}"))?;
        Ok((source, shared.skeleton().clone()))
    }
}

/// The landmark pipeline for `people` people with `model`.
fn pipeline(people: usize, model: ModelKind) -> anyhow::Result<PosePipeline> {
    let defaults = PipelineConfig::default();
    let config = PipelineConfig {
        model,
        tracker: TrackerConfig {
            max_people: people,
            ..defaults.tracker
        },
        ..defaults
    };
    PosePipeline::new(&config).context("pose estimation is not set up (run `rigcast setup vision`)")
}

/// A video file's frames at the model's decode size.
pub(crate) fn open_file(path: &Path) -> anyhow::Result<Box<dyn FrameSource>> {
    let frames = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, DEFAULT_SEQUENCE_FPS)
        .with_context(|| format!("cannot open video {}", path.display()))?;
    Ok(Box::new(frames))
}
