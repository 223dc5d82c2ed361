//! Pose estimation on a video file (`kind = "video"`, `--source video:FILE`; needs
//! `rigcast setup vision`).

use std::path::PathBuf;

use anyhow::Context;
use rigcast_protocol::SourceKind;
use serde::Deserialize;

use super::{file_arg, stem, CliError, KindSpec, Loaded, Opened};

/// A video file, its frames released in real time.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VideoSpec {
    /// The video.
    pub path: PathBuf,
    /// Subject name (default: the file stem).
    pub name: Option<String>,
}

impl KindSpec for VideoSpec {
    const KIND: SourceKind = SourceKind::Video;
    const CLI: Option<&'static str> = Some("video");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        Ok(VideoSpec {
            path: file_arg(arg)?,
            name: None,
        })
    }

    fn to_cli(&self) -> Option<String> {
        self.name
            .is_none()
            .then(|| format!("video:{}", self.path.display()))
    }

    fn file_mut(&mut self) -> Option<&mut PathBuf> {
        Some(&mut self.path)
    }

    fn open(self) -> anyhow::Result<Opened> {
        use rigcast_sources::vision::{
            ffmpeg::DEFAULT_SEQUENCE_FPS, DecodeSize, FfmpegSource, VisionSource,
        };
        let path = &self.path;
        let frames = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, DEFAULT_SEQUENCE_FPS)
            .with_context(|| format!("cannot open video {}", path.display()))?;
        let pipeline = pose_pipeline()?;
        let sk = pipeline.skeleton().clone();
        let source = VisionSource::new(stem(path), Box::new(frames), pipeline, true);
        let name = self.name.unwrap_or_else(|| stem(path));
        Ok((name, Loaded::live(Box::new(source), SourceKind::Video), sk))
    }
}

/// The pose pipeline of a camera or video source, with the hint a user needs when the models
/// are missing.
pub(super) fn pose_pipeline() -> anyhow::Result<rigcast_sources::vision::PosePipeline> {
    use rigcast_sources::vision::{PipelineConfig, PosePipeline};
    PosePipeline::new(&PipelineConfig::default())
        .context("pose estimation is not set up (run `rigcast setup vision`)")
}
