//! Where a frame's time goes (issue 32's speed): per clip, the default pipeline's wall time a
//! frame split into waiting for the decoder, tracking (the landmark runs of the people held,
//! with any second opinion), finding (detector passes and their landmark runs) and the
//! model-free stages, the process's CPU time a frame (the ffmpeg child's apart: under load the
//! wall times swing, the CPU time much less), and the model runs behind them; then each
//! model's cost a run, wall and CPU, on one real frame of the first clip (lite on one crop and
//! two in one call, full, the detector; on one inference thread and on the default number).
//! Clips as in `vision_footage` (`RIGCAST_FOOTAGE_CLIPS` picks by comma-separated name parts,
//! `RIGCAST_FOOTAGE_FRAMES` caps the frames, 0 for all). A benchmark: ignored, run in a release
//! build: `cargo test --release -p rigcast-sources --test vision_profile -- --ignored --nocapture`.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/shared_data.rs"]
mod shared_data;

use std::path::Path;
use std::time::{Duration, Instant};

use glam::Vec2;
use rigcast_sources::vision::detector::PersonDetector;
use rigcast_sources::vision::roi::Roi;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, LandmarkModel, Landmarks, ModelKind, PipelineConfig,
    PosePipeline, RgbFrame, VisionAssets,
};

fn max_frames() -> Option<usize> {
    std::env::var("RIGCAST_FOOTAGE_FRAMES")
        .ok()
        .map(|v| v.parse::<usize>().unwrap())
        .filter(|&n| n > 0)
}

#[derive(Default)]
struct Split {
    frames: u32,
    wait: Duration,
    track: Duration,
    find: Duration,
    solve: Duration,
    total: Duration,
}

fn profile_clip(path: &Path, config: &PipelineConfig) {
    let mut pipeline = PosePipeline::new(config).unwrap();
    let mut source = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut frame = RgbFrame::default();
    let mut split = Split::default();
    let mut first = true;
    let mut clock = Instant::now();
    let mut cpu_start = 0.0;
    while max_frames().is_none_or(|m| (split.frames as usize) < m) {
        let t0 = Instant::now();
        if !source.next_frame(&mut frame).unwrap() {
            break;
        }
        let t1 = Instant::now();
        pipeline.track_frame(&frame).unwrap();
        let t2 = Instant::now();
        pipeline.find_people(&frame).unwrap();
        let t3 = Instant::now();
        if first {
            // As the judge: the clock starts after the first frame.
            first = false;
            clock = t3;
            cpu_start = common::cpu_secs();
            continue;
        }
        split.frames += 1;
        split.wait += t1 - t0;
        split.track += t2 - t1;
        split.find += t3 - t2;
        split.solve += pipeline.solve_time();
    }
    split.total = clock.elapsed();
    let cpu = (common::cpu_secs() - cpu_start) * 1e3 / split.frames.max(1) as f64;
    let n = split.frames.max(1) as f64;
    let ms = |d: Duration| d.as_secs_f64() * 1e3 / n;
    let stats = pipeline.stats();
    let name = path.file_name().unwrap().to_string_lossy();
    let short: String = name.chars().take(28).collect();
    println!(
        "| {short} | {} | {:.1} | {:.2} | {cpu:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} ({:.2}; {:.2}) | {:.3} | {:.3} |",
        source.size().0,
        n / split.total.as_secs_f64(),
        ms(split.total),
        ms(split.wait),
        ms(split.track),
        ms(split.find),
        ms(split.solve),
        stats.inferences as f64 / n,
        stats.finder_inferences as f64 / n,
        stats.beside_inferences as f64 / n,
        stats.second_opinions as f64 / n,
        stats.detections as f64 / n,
    );
}

/// Mean wall time and CPU time (ms) of one call of `f`, after two warm-up calls.
fn time_per_call(runs: u32, mut f: impl FnMut()) -> String {
    f();
    f();
    let t = Instant::now();
    let c = common::cpu_secs();
    for _ in 0..runs {
        f();
    }
    let wall = t.elapsed().as_secs_f64() * 1e3 / runs as f64;
    let cpu = (common::cpu_secs() - c) * 1e3 / runs as f64;
    format!("{wall:.2} ms wall, {cpu:.2} ms CPU")
}

fn model_costs(assets: &VisionAssets, config: &PipelineConfig, clip: &Path) {
    let mut source = FfmpegSource::open_at(clip, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut frame = RgbFrame::default();
    assert!(source.next_frame(&mut frame).unwrap());
    let library = assets.runtime_library();
    let (w, h) = (frame.width as f32, frame.height as f32);
    let roi = Roi::square(Vec2::new(w * 0.5, h * 0.5), w.min(h) * 0.8);
    let rois = [roi, roi];
    let mut outs = [Landmarks::default(); 2];
    for (kind, threads) in [
        (ModelKind::Lite, 1),
        (ModelKind::Lite, config.threads),
        (ModelKind::Full, 1),
        (ModelKind::Full, config.threads),
    ] {
        let path = assets.landmark_model(kind);
        print!("{threads} threads: ");
        let mut model = LandmarkModel::load(&library, &path, threads, 2).unwrap();
        let one = time_per_call(100, || model.infer(&frame, &roi, &mut outs[0]).unwrap());
        let two = time_per_call(100, || {
            model.infer_batch(&frame, &rois, &mut outs).unwrap();
        });
        println!("{kind:?}: one crop {one}, two crops in one call {two}");
    }
    for threads in [1, config.threads] {
        let mut detector =
            PersonDetector::load(&library, &assets.detector_model(), threads, 0.3).unwrap();
        let mut found = Vec::new();
        let d = time_per_call(100, || detector.detect(&frame, &mut found).unwrap());
        println!("{threads} threads: detector: {d} a pass");
    }
}

#[test]
#[ignore = "a benchmark: run in a release build with --ignored --nocapture"]
fn where_a_frame_goes() {
    let Some((assets, config)) = common::default_config_or_skip("where_a_frame_goes") else {
        return;
    };
    let clips = shared_data::footage_clips(&assets.root.join("pose2sim"));
    println!(
        "| clip | decoded width | fps | ms a frame | CPU ms a frame (ffmpeg apart) | waiting for \
         the decoder | tracking | finding | stages | landmark runs a frame (the finder's; beside \
         someone) | second opinions a frame | detector passes a frame |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for clip in &clips {
        profile_clip(clip, &config);
    }
    if let Some(first) = clips.first() {
        model_costs(&assets, &config, first);
    }
}
