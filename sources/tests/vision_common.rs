//! Shared helpers for the vision tests (included with `#[path]`, not a test target itself).
#![allow(clippy::unwrap_used)] // tests may unwrap
#![allow(dead_code)]

use std::path::Path;

use rigcast_sources::vision::{
    FfmpegSource, FrameSource, Landmarks, PipelineConfig, PosePipeline, RgbFrame, VisionAssets,
};

/// The installed assets, or `None` (with a printed reason) when `RIGCAST_SKIP_VISION=1`.
/// Without the setup it fails with the command to run.
pub fn assets_or_skip(test: &str) -> Option<VisionAssets> {
    if std::env::var("RIGCAST_SKIP_VISION").as_deref() == Ok("1") {
        eprintln!("SKIP {test}: RIGCAST_SKIP_VISION=1");
        return None;
    }
    let assets = VisionAssets::from_env();
    assert!(
        assets.is_ready(),
        "{test}: vision assets are not installed in {}; run `scripts/setup-vision.sh` \
         (or `rigcast setup vision`), or set RIGCAST_SKIP_VISION=1 to skip",
        assets.root.display()
    );
    Some(assets)
}

/// Runs the pipeline over a video; one entry per frame (output landmarks, and in `raw` the
/// model's landmarks after the flip guard, before smoothing and constant lengths).
pub fn run_video_raw(
    path: &Path,
    config: &PipelineConfig,
    raw: &mut Vec<Option<Landmarks>>,
) -> (f64, Vec<Option<Landmarks>>, PosePipeline) {
    let mut source = FfmpegSource::open(path).unwrap();
    let fps = source.fps().unwrap();
    let mut pipeline = PosePipeline::new(config).unwrap();
    let mut pose = pipeline.skeleton().rest_pose();
    let mut frame = RgbFrame::default();
    let mut out = Vec::new();
    while source.next_frame(&mut frame).unwrap() {
        let lm = pipeline.process(&frame, &mut pose).unwrap().copied();
        raw.push(lm.map(|_| *pipeline.raw_landmarks()));
        out.push(lm);
    }
    (fps, out, pipeline)
}

/// [`run_video_raw`] without the raw landmarks.
pub fn run_video(
    path: &Path,
    config: &PipelineConfig,
) -> (f64, Vec<Option<Landmarks>>, PosePipeline) {
    run_video_raw(path, config, &mut Vec::new())
}

/// Coefficient of variation (std / mean).
pub fn cv(values: &[f32]) -> f32 {
    let n = values.len() as f32;
    let mean = values.iter().sum::<f32>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / n;
    var.sqrt() / mean
}

/// Frames of a file, each changed (or the stream ended) by `edit` as it is read: `edit`
/// returns false to end the stream there.
pub struct Edited<F> {
    pub inner: FfmpegSource,
    pub edit: F,
}

impl<F: FnMut(&mut RgbFrame) -> bool + Send> FrameSource for Edited<F> {
    fn describe(&self) -> &str {
        self.inner.describe()
    }
    fn fps(&self) -> Option<f64> {
        self.inner.fps()
    }
    fn size(&self) -> (u32, u32) {
        self.inner.size()
    }
    fn next_frame(
        &mut self,
        out: &mut RgbFrame,
    ) -> Result<bool, rigcast_sources::vision::VisionError> {
        Ok(self.inner.next_frame(out)? && (self.edit)(out))
    }
}
