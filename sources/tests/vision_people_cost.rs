//! What the default (two identity slots) costs against `--people 1` (`max_people: 1`) on the
//! same footage (issue 32: one person in view must cost no more than `--people 1`). Per clip of
//! `../shared/data/video` and the pose2sim clips (discovered by listing; `RIGCAST_FOOTAGE_CLIPS`
//! picks by comma-separated name parts as in `vision_footage`): model runs a frame (landmark
//! crops and detector passes: the work, whatever the machine's load), this process's CPU time a
//! frame (the decoder's process apart) and frames a second with decoding, the two settings run
//! alternately `RIGCAST_COST_ROUNDS` times (2 by default; the medians of each are printed) so
//! that the load moves both alike. A benchmark, not a
//! timed test: ignored, run in a release build:
//! `cargo test --release -p rigcast-sources --test vision_people_cost -- --ignored --nocapture`.
//! Asserted: both settings read the same frames; the figures are printed, not judged (the
//! machine's load decides the frame rates; the model runs are the work itself).
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/shared_data.rs"]
mod shared_data;

use std::path::Path;
use std::time::Instant;

use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, PipelineConfig, PosePipeline, RgbFrame,
};

/// One run over a clip.
struct Run {
    frames: usize,
    /// Frames with person `#0`.
    seen: usize,
    /// Landmark runs plus detector passes.
    model_runs: u64,
    /// Detector passes.
    detections: u64,
    /// Runs of the second-opinion model.
    second_opinions: u64,
    /// Frames a second with decoding, the clock started after the first frame.
    fps: f64,
    /// This process's CPU time a frame (ms; the decoder's own process apart), over the same
    /// frames: what the work costs, less swayed by the load than the frame rate.
    cpu_ms: f64,
}

fn run(path: &Path, config: &PipelineConfig) -> Run {
    let mut pipeline = PosePipeline::new(config).unwrap();
    let mut source = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut frame = RgbFrame::default();
    let (mut frames, mut seen) = (0usize, 0usize);
    let mut started = None;
    while source.next_frame(&mut frame).unwrap() {
        pipeline.process_frame(&frame).unwrap();
        frames += 1;
        seen += usize::from(pipeline.person(0).is_some());
        started.get_or_insert_with(|| (Instant::now(), common::cpu_secs()));
    }
    let (secs, cpu) = started.map_or((0.0, 0.0), |(t, c)| {
        (t.elapsed().as_secs_f64(), common::cpu_secs() - c)
    });
    let stats = pipeline.stats();
    let timed = frames.saturating_sub(1) as f64;
    Run {
        frames,
        seen,
        model_runs: stats.inferences + stats.detections,
        detections: stats.detections,
        second_opinions: stats.second_opinions,
        fps: timed / secs.max(1e-9),
        cpu_ms: cpu * 1e3 / timed.max(1.0),
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
#[ignore = "a benchmark: run in a release build with --ignored --nocapture"]
fn the_default_costs_what_one_person_costs_where_one_is_in_view() {
    let Some((assets, default)) = common::default_config_or_skip("vision_people_cost") else {
        return;
    };
    let model = std::env::var("RIGCAST_TEST_MODEL").map_or(default.model, |m| m.parse().unwrap());
    let default = PipelineConfig { model, ..default };
    let mut one = default.clone();
    one.tracker.max_people = 1;
    let rounds: usize = std::env::var("RIGCAST_COST_ROUNDS").map_or(2, |r| r.parse().unwrap());
    println!(
        "model {}, {rounds} alternating rounds, load {}",
        model.as_str(),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    println!("| clip | frames | #0 seen, default / --people 1 | model runs a frame, default / --people 1 (detector passes; second-model runs) | CPU ms a frame, default / --people 1 | CPU ratio | fps, default / --people 1 | fps ratio |");
    println!("|---|---|---|---|---|---|---|---|");
    for clip in shared_data::footage_clips(&assets.root.join("pose2sim")) {
        let name = clip.file_name().unwrap().to_string_lossy().into_owned();
        let (mut fps_d, mut fps_1) = (Vec::new(), Vec::new());
        let (mut cpu_d, mut cpu_1) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..rounds.max(1) {
            let d = run(&clip, &default);
            let o = run(&clip, &one);
            fps_d.push(d.fps);
            fps_1.push(o.fps);
            cpu_d.push(d.cpu_ms);
            cpu_1.push(o.cpu_ms);
            last = Some((d, o));
        }
        let (d, o) = last.unwrap();
        assert_eq!(d.frames, o.frames, "{name}: frame counts differ");
        let n = d.frames.max(1) as f64;
        let per_frame = |r: &Run| {
            format!(
                "{:.2} ({:.2}; {:.2})",
                r.model_runs as f64 / n,
                r.detections as f64 / n,
                r.second_opinions as f64 / n
            )
        };
        let (fd, f1) = (median(fps_d), median(fps_1));
        let (cd, c1) = (median(cpu_d), median(cpu_1));
        println!(
            "| {name} | {} | {} / {} | {} / {} | {cd:.2} / {c1:.2} | {:.2} | {fd:.1} / {f1:.1} | {:.2} |",
            d.frames,
            d.seen,
            o.seen,
            per_frame(&d),
            per_frame(&o),
            cd / c1.max(1e-9),
            fd / f1
        );
    }
    println!(
        "load at the end {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}
