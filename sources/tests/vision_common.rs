//! Shared helpers for the vision tests (included with `#[path]`, not a test target itself; also
//! by `server/tests/pose_cli.rs`).
#![allow(clippy::unwrap_used)] // tests may unwrap
#![allow(dead_code)]

use std::path::Path;

use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    FfmpegSource, FrameSource, Landmarks, PipelineConfig, PosePipeline, RgbFrame, VisionAssets,
};

/// Limb segments whose length must stay constant: (name, joint a, joint b).
pub const SEGMENTS: [(&str, usize, usize); 6] = [
    ("left upper arm", idx::LEFT_SHOULDER, idx::LEFT_ELBOW),
    ("right upper arm", idx::RIGHT_SHOULDER, idx::RIGHT_ELBOW),
    ("left thigh", idx::LEFT_HIP, idx::LEFT_KNEE),
    ("right thigh", idx::RIGHT_HIP, idx::RIGHT_KNEE),
    ("left shin", idx::LEFT_KNEE, idx::LEFT_ANKLE),
    ("right shin", idx::RIGHT_KNEE, idx::RIGHT_ANKLE),
];

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

/// The installed assets and the default pipeline configuration on them, or `None` as
/// [`assets_or_skip`].
pub fn default_config_or_skip(test: &str) -> Option<(VisionAssets, PipelineConfig)> {
    let assets = assets_or_skip(test)?;
    let config = PipelineConfig {
        assets: assets.clone(),
        ..PipelineConfig::default()
    };
    Some((assets, config))
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

/// Left/right never swap between consecutive frames: the hip and shoulder lines (left minus
/// right, world space) keep their direction from one frame to the next. `what` starts the
/// failure message.
pub fn assert_sides_never_swap(frames: &[Option<Landmarks>], what: &str) {
    for w in frames.windows(2) {
        let (Some(p), Some(c)) = (&w[0], &w[1]) else {
            continue;
        };
        for (l, r) in [
            (idx::LEFT_HIP, idx::RIGHT_HIP),
            (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER),
        ] {
            let before = p.world[l] - p.world[r];
            let after = c.world[l] - c.world[r];
            assert!(
                before.dot(after) > 0.0,
                "{what}: sides swapped ({before} → {after})"
            );
        }
    }
}

/// Frames whose hip or shoulder line (left minus right, world) points against the previous
/// frame's: left and right swapped between them.
pub fn side_swaps(frames: &[Option<Landmarks>]) -> usize {
    frames
        .windows(2)
        .filter(|w| {
            let (Some(p), Some(c)) = (&w[0], &w[1]) else {
                return false;
            };
            [
                (idx::LEFT_HIP, idx::RIGHT_HIP),
                (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER),
            ]
            .iter()
            .any(|&(l, r)| (p.world[l] - p.world[r]).dot(c.world[l] - c.world[r]) <= 0.0)
        })
        .count()
}

/// Coefficient of variation (std / mean).
/// Mean absolute difference of two frames' bytes (levels a channel); they must be one size.
pub fn mean_abs_diff(a: &RgbFrame, b: &RgbFrame) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let sum: u64 = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| u64::from(x.abs_diff(*y)))
        .sum();
    sum as f64 / a.data.len() as f64
}

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

/// Fields `at` and `at + 1` of `/proc/self/stat` summed (clock ticks) in seconds, counted from
/// the first field after the process name (the line's third).
fn stat_secs(at: usize) -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap();
    let after = &stat[stat.rfind(')').unwrap() + 2..];
    let fields: Vec<&str> = after.split(' ').collect();
    let ticks: f64 = fields[at].parse::<f64>().unwrap() + fields[at + 1].parse::<f64>().unwrap();
    ticks / 100.0
}

/// The process's CPU time so far (user + system, every thread), seconds.
pub fn cpu_secs() -> f64 {
    // utime and stime are fields 14 and 15 of the line (11 and 12 after the name).
    stat_secs(11)
}

/// The CPU time (user + system) of this process's children that have ended and been waited
/// for, seconds: an ffmpeg decoder's once its source is dropped.
pub fn children_cpu_secs() -> f64 {
    // cutime and cstime are fields 16 and 17 of the line.
    stat_secs(13)
}

/// The calling thread's CPU time so far, seconds (the scheduler's count, in nanoseconds): for
/// leaving a test's own work out of the process's.
pub fn thread_cpu_secs() -> f64 {
    let stat = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap_or_default();
    let ns: f64 = stat
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or(0.0);
    ns * 1e-9
}
