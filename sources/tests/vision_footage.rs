//! The judge on real footage: every clip of `../shared/data/video` (discovered from the folder)
//! and the pose2sim clips `scripts/setup-vision.sh` installs, run with the default settings and
//! side by side with MediaPipe Pose 0.10.14 (Python, its defaults: one person, full model) on
//! the same frames in the same run, clip by clip in turn.
//!
//! Per clip: coverage of every identity slot, identity jumps (a slot's hips moving more than
//! 15 % of the frame between frames at most 2 apart; MediaPipe's by the same measure beside
//! them; both sides' output landmarks, smoothed as each gives them by default), left/right agreement with MediaPipe where
//! its reading is decisive and steady and both show the same person, the detector runs per frame, and the
//! frame rate with decoding on both sides. Bounds (issue 32): person `#0`'s coverage within one
//! point of MediaPipe's or above, no identity jumps, left/right right on at least 99 % of the
//! frames with a reference, the detector at most once per frame, and (release builds only: a
//! debug build's frame rate says nothing) at least twice MediaPipe's frame rate.
//!
//! MediaPipe comes from `scripts/setup-mediapipe.sh` (a private venv); without it the test
//! prints rigcast's figures and skips the comparison with the reason. Ignored until today's
//! tracker meets the bounds (BENCHMARKS.md: it does not on every clip);
//! `scripts/bench-vision-footage.sh` runs it with them asserted (`RIGCAST_FOOTAGE_ACCEPTANCE=1`;
//! without it the clips outside them are listed). Settings:
//! `RIGCAST_TEST_MODEL` (lite, the default, or full), `RIGCAST_FOOTAGE_FRAMES` (frames per
//! clip, 60 by default, 0 for all), `RIGCAST_FOOTAGE_CLIPS` (only clips whose names hold one
//! of these comma-separated parts), `RIGCAST_MEDIAPIPE_PYTHON` (the venv's python),
//! `RIGCAST_MEDIAPIPE_CACHE` (a folder keeping MediaPipe's landmarks between runs while
//! iterating; its frame rate is then not compared).
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/shared_data.rs"]
mod shared_data;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use glam::Vec2;
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, ModelKind, PipelineConfig, PosePipeline, RgbFrame,
    VisionAssets,
};

/// File name endings of videos in the footage folder.
const VIDEO_ENDINGS: [&str; 5] = ["mp4", "avi", "mkv", "mov", "webm"];

/// An identity jump: hips moving further than this fraction of the frame's longer side
/// between frames at most [`JUMP_SPAN`] apart.
const JUMP_FRACTION: f32 = 0.15;
const JUMP_SPAN: usize = 2;

/// Image points of one person in one frame (source pixels) with visibilities.
type Points = Vec<[f32; 3]>;

/// rigcast's run over one clip.
struct Ours {
    width: f32,
    height: f32,
    /// Per frame, per slot: the output landmarks' image points when seen (smoothed, what a
    /// user gets, as MediaPipe's are by default).
    slots: Vec<Vec<Option<Points>>>,
    fps: f64,
    detections: u64,
    /// Landmark model runs (crops).
    inferences: u64,
}

/// MediaPipe's run over the same frames.
struct Theirs {
    frames: Vec<Option<Points>>,
    fps: f64,
}

fn frames_per_clip() -> Option<usize> {
    match std::env::var("RIGCAST_FOOTAGE_FRAMES") {
        Ok(v) => Some(v.parse::<usize>().unwrap()).filter(|&n| n > 0),
        Err(_) => Some(60),
    }
}

fn model() -> ModelKind {
    std::env::var("RIGCAST_TEST_MODEL")
        .map(|m| m.parse().unwrap())
        .unwrap_or_default()
}

/// Every video of the footage folder and the pose2sim folder, sorted, found by listing; only
/// those whose name holds one of `RIGCAST_FOOTAGE_CLIPS`' comma-separated parts when set.
fn clips(assets: &VisionAssets) -> Vec<PathBuf> {
    let only = std::env::var("RIGCAST_FOOTAGE_CLIPS").unwrap_or_default();
    let wanted = |p: &Path| {
        let name = p.file_name().unwrap_or_default().to_string_lossy();
        only.is_empty() || only.split(',').any(|part| name.contains(part))
    };
    let mut found = Vec::new();
    let video = shared_data::shared_data_root().join("video");
    if !video.is_dir() {
        println!("SKIP part: no footage folder at {}", video.display());
    }
    for dir in [video, assets.root.join("pose2sim")] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut here: Vec<PathBuf> = entries
            .filter_map(|e| Some(e.ok()?.path()))
            .filter(|p| {
                p.extension()
                    .is_some_and(|e| VIDEO_ENDINGS.contains(&e.to_string_lossy().as_ref()))
                    && wanted(p)
            })
            .collect();
        here.sort();
        found.extend(here);
    }
    found
}

fn points(lm: &rigcast_sources::vision::Landmarks) -> Points {
    lm.image[..33].iter().map(|p| [p.x, p.y, p.w]).collect()
}

fn run_ours(path: &Path, config: &PipelineConfig, max: Option<usize>) -> Ours {
    let mut pipeline = PosePipeline::new(config).unwrap();
    let started = Instant::now();
    let mut source = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let (width, height) = source.size();
    let mut frame = RgbFrame::default();
    let mut slots = Vec::new();
    while max.is_none_or(|m| slots.len() < m) && source.next_frame(&mut frame).unwrap() {
        pipeline.process_frame(&frame).unwrap();
        slots.push(
            (0..pipeline.num_people())
                .map(|s| pipeline.person(s).map(points))
                .collect(),
        );
    }
    let secs = started.elapsed().as_secs_f64();
    Ours {
        width: width as f32,
        height: height as f32,
        fps: slots.len() as f64 / secs,
        slots,
        detections: pipeline.stats().detections,
        inferences: pipeline.stats().inferences,
    }
}

/// The venv's python with MediaPipe 0.10.14, or the reason there is none.
fn mediapipe_python() -> Result<PathBuf, String> {
    let python = std::env::var_os("RIGCAST_MEDIAPIPE_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let home = std::env::var_os("RIGCAST_HOME")
                .map(PathBuf::from)
                .unwrap_or_else(|| {
                    PathBuf::from(std::env::var_os("HOME").unwrap_or_default())
                        .join(".cache/rigcast")
                });
            home.join("mediapipe-0.10.14/bin/python")
        });
    let ok = Command::new(&python)
        .args(["-c", "import mediapipe"])
        .output()
        .is_ok_and(|o| o.status.success());
    if ok {
        Ok(python)
    } else {
        Err(format!(
            "MediaPipe 0.10.14 is not installed at {} (scripts/setup-mediapipe.sh installs it)",
            python.display()
        ))
    }
}

/// MediaPipe's run over `path` (its first `max` frames): in this run, or read back from
/// `RIGCAST_MEDIAPIPE_CACHE` (a folder: `CLIP.json`, its landmarks over every frame, and
/// `CLIP.txt`, its summary line, written there by the first run) while iterating on the
/// tracker. A cached frame rate is from another run, so the speed ratio is not judged then.
fn run_theirs(python: &Path, path: &Path, max: Option<usize>) -> (Theirs, bool) {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let cache = std::env::var_os("RIGCAST_MEDIAPIPE_CACHE").map(PathBuf::from);
    let (json_path, text_path, cached) = match &cache {
        Some(dir) => {
            let (j, t) = (
                dir.join(format!("{name}.json")),
                dir.join(format!("{name}.txt")),
            );
            let cached = j.is_file() && t.is_file();
            (j, t, cached)
        }
        None => {
            let temp =
                std::env::temp_dir().join(format!("rigcast-footage-{}-{name}", std::process::id()));
            (
                temp.with_extension("json"),
                temp.with_extension("txt"),
                false,
            )
        }
    };
    if !cached {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/bench_mediapipe.py");
        let mut cmd = Command::new(python);
        cmd.arg(&script)
            .arg(path)
            .args(["full", "1", "--landmarks"])
            .arg(&json_path);
        // A cache holds every frame, so that any bound reads it.
        if let Some(m) = max.filter(|_| cache.is_none()) {
            cmd.args(["--max-frames", &m.to_string()]);
        }
        let output = cmd.output().unwrap();
        assert!(
            output.status.success(),
            "MediaPipe on {}: {}",
            path.display(),
            String::from_utf8_lossy(&output.stderr)
        );
        std::fs::write(&text_path, &output.stdout).unwrap();
    }
    let stdout = std::fs::read_to_string(&text_path).unwrap();
    let fps = stdout
        .split_whitespace()
        .find_map(|w| w.strip_prefix("fps_with_decoding="))
        .unwrap()
        .parse()
        .unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    if cache.is_none() {
        let _ = std::fs::remove_file(&json_path);
        let _ = std::fs::remove_file(&text_path);
    }
    let frames = json["frames"]
        .as_array()
        .unwrap()
        .iter()
        .take(max.unwrap_or(usize::MAX))
        .map(|f| {
            f.as_array().map(|pts| {
                pts.iter()
                    .map(|p| {
                        let v = |i: usize| p[i].as_f64().unwrap() as f32;
                        [v(0), v(1), v(2)]
                    })
                    .collect()
            })
        })
        .collect();
    (Theirs { frames, fps }, cached)
}

fn at(p: &Points, i: usize) -> Vec2 {
    Vec2::new(p[i][0], p[i][1])
}

fn hips(p: &Points) -> Vec2 {
    (at(p, idx::LEFT_HIP) + at(p, idx::RIGHT_HIP)) * 0.5
}

fn shoulders(p: &Points) -> Vec2 {
    (at(p, idx::LEFT_SHOULDER) + at(p, idx::RIGHT_SHOULDER)) * 0.5
}

/// How much the labels face the camera in the picture: left-minus-right of shoulders and hips
/// (their mean) across the spine, in torso lengths (about 0.6 from the front, negative when
/// the left side is on the picture's left of an upright spine, near 0 from the side).
fn facing(p: &Points) -> f32 {
    let across = (at(p, idx::LEFT_SHOULDER) - at(p, idx::RIGHT_SHOULDER) + at(p, idx::LEFT_HIP)
        - at(p, idx::RIGHT_HIP))
        * 0.5;
    let up = shoulders(p) - hips(p);
    -across.perp_dot(up) / up.length_squared().max(1e-6)
}

/// Identity jumps of one person's frames (`None` where not seen): frame pairs at most
/// [`JUMP_SPAN`] apart where the hips moved further than [`JUMP_FRACTION`] of the frame's
/// longer side `side`.
fn jumps<'a>(frames: impl Iterator<Item = Option<&'a Points>>, side: f32) -> usize {
    let limit = JUMP_FRACTION * side;
    let hip: Vec<Option<Vec2>> = frames.map(|p| p.map(hips)).collect();
    (0..hip.len())
        .filter(|&i| {
            (1..=JUMP_SPAN).any(|d| {
                matches!((hip[i], hip.get(i + d).copied().flatten()),
                    (Some(a), Some(b)) if a.distance(b) > limit)
            })
        })
        .count()
}

/// MediaPipe's reading counts as a reference at frames where it is decisive (|facing| at
/// least this) ...
const DECISIVE: f32 = 0.3;
/// ... the same way round over this many frames either side (its single-frame flips, which
/// it has on views the model finds ambiguous, are no reference) ...
const STEADY: usize = 2;

/// Frames where MediaPipe's left/right reading is a reference (see [`DECISIVE`], [`STEADY`])
/// and rigcast's `#0` is the same person (hips within half a torso): (such frames, rigcast's
/// labels the same way round).
fn left_right(ours: &Ours, theirs: &Theirs) -> (usize, usize) {
    let way: Vec<Option<f32>> = theirs
        .frames
        .iter()
        .map(|f| {
            f.as_ref()
                .map(facing)
                .filter(|v| v.abs() >= DECISIVE)
                .map(f32::signum)
        })
        .collect();
    let (mut reference, mut agree) = (0, 0);
    for (i, (slots, mp)) in ours.slots.iter().zip(&theirs.frames).enumerate() {
        let (Some(us), Some(mp), Some(sign)) = (&slots[0], mp, way[i]) else {
            continue;
        };
        let steady = (i.saturating_sub(STEADY)..=(i + STEADY).min(way.len() - 1))
            .all(|j| way[j] == Some(sign));
        let torso = shoulders(mp).distance(hips(mp));
        if !steady || hips(us).distance(hips(mp)) > 0.5 * torso {
            continue;
        }
        reference += 1;
        agree += usize::from(facing(us) * sign > 0.0);
    }
    (reference, agree)
}

fn percent(n: usize, of: usize) -> f64 {
    100.0 * n as f64 / of.max(1) as f64
}

#[test]
#[ignore = "issue 32: the default tracker does not meet these bounds on every clip yet; scripts/bench-vision-footage.sh runs it"]
fn default_settings_keep_the_person_against_mediapipe_on_real_footage() {
    let Some((assets, config)) = common::default_config_or_skip("vision_footage") else {
        return;
    };
    let config = PipelineConfig {
        model: model(),
        ..config
    };
    let clips = clips(&assets);
    if clips.is_empty() {
        println!("SKIP vision_footage: no clips found");
        return;
    }
    let mediapipe = mediapipe_python();
    if let Err(reason) = &mediapipe {
        println!("SKIP the comparison with MediaPipe: {reason}");
    }
    let max = frames_per_clip();
    let speed_judged = !cfg!(debug_assertions);
    if !speed_judged {
        println!("frame rates not judged: a debug build");
    }
    println!(
        "model {}, {} frames per clip at most, load {}",
        config.model.as_str(),
        max.map_or("all".into(), |m| m.to_string()),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    println!("| clip | frames | coverage per slot % | MediaPipe % | jumps (MediaPipe) | left/right % (frames) | detector runs | model runs / frame | fps | MediaPipe fps | ratio |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for clip in &clips {
        let name = clip.file_name().unwrap().to_string_lossy().into_owned();
        let ours = run_ours(clip, &config, max);
        let n = ours.slots.len();
        let slots = ours.slots.first().map_or(0, Vec::len);
        let coverage: Vec<f64> = (0..slots)
            .map(|s| percent(ours.slots.iter().filter(|f| f[s].is_some()).count(), n))
            .collect();
        let side = ours.width.max(ours.height);
        let our_jumps: usize = (0..slots)
            .map(|s| jumps(ours.slots.iter().map(|f| f[s].as_ref()), side))
            .sum();
        if our_jumps > 0 {
            failures.push(format!("{name}: {our_jumps} identity jumps"));
        }
        if ours.detections > n as u64 {
            failures.push(format!(
                "{name}: {} detector runs over {n} frames",
                ours.detections
            ));
        }
        let coverage_text = coverage
            .iter()
            .map(|c| format!("{c:.1}"))
            .collect::<Vec<_>>()
            .join(" / ");
        let mut row = format!(
            "| {name} | {n} | {coverage_text} | {{mp}} | {our_jumps} ({{mpjumps}}) | {{lr}} | {} | {:.2} | {:.1} | {{mpfps}} | {{ratio}} |",
            ours.detections,
            ours.inferences as f64 / n.max(1) as f64,
            ours.fps
        );
        if let Ok(python) = &mediapipe {
            let (theirs, cached) = run_theirs(python, clip, max);
            let theirs_cov = percent(theirs.frames.iter().filter(|f| f.is_some()).count(), n);
            let (reference, agree) = left_right(&ours, &theirs);
            let ratio = ours.fps / theirs.fps;
            row = row
                .replace("{mp}", &format!("{theirs_cov:.1}"))
                .replace(
                    "{mpjumps}",
                    &jumps(theirs.frames.iter().map(Option::as_ref), side).to_string(),
                )
                .replace(
                    "{lr}",
                    &format!("{:.1} ({reference})", percent(agree, reference)),
                )
                .replace("{mpfps}", &format!("{:.1}", theirs.fps))
                .replace(
                    "{ratio}",
                    &if cached {
                        "- (cached)".into()
                    } else {
                        format!("{ratio:.2}")
                    },
                );
            if coverage.first().copied().unwrap_or(0.0) < theirs_cov - 1.0 {
                failures.push(format!(
                    "{name}: person #0 in {:.1} % of frames, MediaPipe {theirs_cov:.1} %",
                    coverage[0]
                ));
            }
            if reference > 0 && percent(agree, reference) < 99.0 {
                failures.push(format!(
                    "{name}: left/right as MediaPipe in {agree} of {reference} frames"
                ));
            }
            if speed_judged && !cached && ratio < 2.0 {
                failures.push(format!("{name}: {ratio:.2}× MediaPipe's frame rate"));
            }
        } else {
            row = row
                .replace("{mp}", "-")
                .replace("{mpjumps}", "-")
                .replace("{lr}", "-")
                .replace("{mpfps}", "-")
                .replace("{ratio}", "-");
        }
        println!("{row}");
    }
    println!(
        "load at the end {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    if std::env::var("RIGCAST_FOOTAGE_ACCEPTANCE").as_deref() == Ok("1") {
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    } else if !failures.is_empty() {
        println!(
            "outside issue 32's bounds (asserted with RIGCAST_FOOTAGE_ACCEPTANCE=1):\n{}",
            failures.join("\n")
        );
    }
}
