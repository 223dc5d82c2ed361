//! Vision throughput and latency: decoded frame → landmarks → rotations, lite model, on the
//! pose2sim demo footage (1080×1920). Frames are decoded in advance so decoding is not timed.
//!
//! Besides criterion's figures, prints `fps` and per-frame `p50`/`p95` latency over a plain
//! timed loop, the numbers BENCHMARKS.md records. Skips with a message when
//! `scripts/setup-vision.sh` has not been run.

use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use rigcast_sources::vision::{
    FfmpegSource, FrameSource, ModelKind, PipelineConfig, PosePipeline, RgbFrame, VisionAssets,
};

fn load_frames(assets: &VisionAssets) -> Vec<RgbFrame> {
    let mut source = match FfmpegSource::open(&assets.pose2sim_video(1)) {
        Ok(s) => s,
        Err(e) => panic!("cannot open benchmark video: {e}"),
    };
    let mut frames = Vec::new();
    let mut frame = RgbFrame::default();
    while matches!(source.next_frame(&mut frame), Ok(true)) {
        frames.push(frame.clone());
    }
    frames
}

fn bench_vision(c: &mut Criterion) {
    let assets = VisionAssets::from_env();
    if !assets.is_ready() {
        eprintln!(
            "SKIP vision bench: assets missing in {}; run scripts/setup-vision.sh",
            assets.root.display()
        );
        return;
    }
    let frames = load_frames(&assets);
    let config = PipelineConfig {
        assets: assets.clone(),
        model: ModelKind::Lite,
        ..PipelineConfig::default()
    };
    let mut pipeline = match PosePipeline::new(&config) {
        Ok(p) => p,
        Err(e) => panic!("cannot build pipeline: {e}"),
    };
    let mut pose = pipeline.skeleton().rest_pose();
    // Warm up: the first frame searches; tracking is the steady state being measured.
    for f in frames.iter().take(10) {
        let _ = pipeline.process(f, &mut pose);
    }

    // Plain timed loop over the footage, three passes, for fps and latency percentiles.
    let mut times_ms = Vec::with_capacity(frames.len() * 3);
    let start = Instant::now();
    for _ in 0..3 {
        for f in &frames {
            let t = Instant::now();
            let _ = pipeline.process(f, &mut pose);
            times_ms.push(t.elapsed().as_secs_f64() * 1000.0);
        }
    }
    let total = start.elapsed().as_secs_f64();
    times_ms.sort_by(|a, b| a.total_cmp(b));
    let pct = |p: f64| times_ms[((times_ms.len() - 1) as f64 * p).round() as usize];
    eprintln!(
        "vision lite 1080x1920: {:.1} fps over {} frames; per-frame p50 {:.1} ms, p95 {:.1} ms, \
         max {:.1} ms; tracker {:?}",
        times_ms.len() as f64 / total,
        times_ms.len(),
        pct(0.5),
        pct(0.95),
        pct(1.0),
        pipeline.stats()
    );

    let mut i = 0;
    c.bench_function("vision_lite_frame_to_rotations", |b| {
        b.iter(|| {
            let f = &frames[i % frames.len()];
            i += 1;
            let _ = pipeline.process(f, &mut pose);
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30);
    targets = bench_vision
}
criterion_main!(benches);
