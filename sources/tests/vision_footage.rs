//! The judge on real footage: every clip of `../shared/data/video` (discovered from the folder)
//! and the pose2sim clips `scripts/setup-vision.sh` installs, run with the default settings and
//! side by side with MediaPipe Pose 0.10.14 (Python, its defaults: one person, full model; and
//! for speed, asked for the clip's people) on the same frames in the same run, clip by clip in
//! turn.
//!
//! Per clip: coverage of every identity slot (beside MediaPipe's, the frames where `#0` shows
//! someone and MediaPipe nobody: coverage no anchor confirms, see `unconfirmed`), MediaPipe's
//! one person followed through the slots (the share of its frames some slot shows that person,
//! and how often the slot showing them changes: see `followed`), identity jumps (a slot's hips
//! moving more than 15 % of the source frame's longer side between frames at most 2 apart: the
//! issue's measure, which the bound uses; beside it, those that also move so against the scene's own motion —
//! a camera's whip carries a person as far, so the difference is what pans account for;
//! MediaPipe's by the same measures beside them; both sides' output landmarks, smoothed as each gives them
//! by default), left/right agreement, the detector runs per frame, the landmark model runs per
//! frame (with the second-opinion model's where the first's left/right readings were in doubt),
//! and the frame rate with decoding on both sides (each clock started after the first frame).
//! Beside the frame rates, the CPU time a frame with decoding on both sides: each program's
//! process after its first frame plus the whole of its ffmpeg decoder's (rigcast's less the
//! judge's own measure of the scene's motion); on a shared machine the load swings the frame
//! rates, each program's and so their ratio, far more than the CPU a frame (see `cpu_text`).
//! Left/right is judged against the 3D reference where the clip is a camera of a calibrated rig
//! (the pose2sim single-person demo: `common/reference3d.rs`, triangulated from the rig's other
//! cameras), elsewhere against MediaPipe where its reading is decisive and steady and both show
//! the same person. Bounds (issue 32): person `#0`'s coverage within one point of MediaPipe's or
//! above, no identity jumps, left/right right on at least 99 % of the frames with a reference,
//! the detector at most once per frame, and (release builds only: a debug build's frame rate
//! says nothing) at least twice the frame rate of MediaPipe asked for the clip's people.
//!
//! The speed bound's anchor is MediaPipe with as many people as the clip holds (the issue:
//! "person count as in the clip"), up to as many as rigcast tracks by default (2): rigcast
//! runs a landmark model per person, and so does MediaPipe's own multi-person tracker, the
//! Tasks API's `PoseLandmarker` with `num_poses` (`scripts/bench_mediapipe.py`; full model,
//! its default). The count comes from that independent program on the clip's frames, never from
//! a file name or `SOURCES.md`: MediaPipe asked for 2 runs on every clip, and a clip holds two
//! people when it finds two in at least half the frames judged (a round rule, the same for every
//! clip: a clip where the second person shows only now and then is a one-person clip with a
//! passer-by). That same run is the anchor of a two-person clip; a one-person clip's is
//! MediaPipe's one-person tracker (`solutions.pose`, the run coverage and left/right are judged
//! against, as MediaPipe's defaults are). Both ratios are printed: to one person, and to the
//! clip's people (the bound). Asked for two, MediaPipe runs its detector on every frame where it
//! holds fewer than two, so on a clip where it finds one it is slower than its one-person
//! tracker (the reason not to judge every clip against it).
//!
//! Two tests run the judge: `footage_judge_reports_every_clip` (every test run, CI's included:
//! the table in the log and the clips outside the bounds listed; asserted: both programs ran on
//! every clip and read the same frames) and the acceptance test, ignored until today's tracker
//! meets the bounds (BENCHMARKS.md: it does not on every clip), which asserts them;
//! `scripts/bench-vision-footage.sh` runs it in a release build over every frame. MediaPipe
//! comes from `scripts/setup-mediapipe.sh` (a private venv); without it the tests print
//! rigcast's figures and skip the comparison with the reason. Settings: `RIGCAST_TEST_MODEL`
//! (lite, the default, or full), `RIGCAST_FOOTAGE_FRAMES` (frames per clip, 60 by default, 0
//! for all), `RIGCAST_FOOTAGE_CLIPS` (only clips whose names hold one of these comma-separated
//! parts), `RIGCAST_MEDIAPIPE_PYTHON` (the venv's python), `RIGCAST_MEDIAPIPE_CACHE` (a folder
//! keeping MediaPipe's landmarks between runs while iterating; its frame rate is then not
//! compared), `RIGCAST_FOOTAGE_DUMP` (a folder where each clip's output is written as
//! `CLIP.MODEL.json`: per frame, per slot, the 33 image points `[x, y, visibility]` in source
//! pixels or null, to look at what the figures count beside MediaPipe's cached landmarks),
//! `RIGCAST_DECODE_EXACT_RGB` (rigcast's decoder uses ffmpeg's exact RGB conversion instead of
//! its default, 1-4 levels apart: a second run with it shows which figures flip with the
//! rounding; MediaPipe's side decodes as before), `RIGCAST_DECODE_NUDGE` (`shift`, `level` or
//! `deblock`: rigcast's decoded picture a pixel to the left, a level brighter, or decoded
//! without H.264's loop filter; runs under each, against the run without, show how much of a
//! figure is chance: BENCHMARKS.md, issue 32).
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/mediapipe.rs"]
mod mediapipe;
#[path = "common/multiview.rs"]
mod multiview;
#[path = "common/reference3d.rs"]
mod reference3d;
#[path = "common/scene_motion.rs"]
mod scene_motion;
#[path = "common/shared_data.rs"]
mod shared_data;

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec2, Vec2};
use mediapipe::{
    mediapipe_python, run_mediapipe, run_mediapipe_crowd, MediaPipeCrowd, MediaPipeRun, Points,
};
use reference3d::Rig;
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, ModelKind, PipelineConfig, PosePipeline, RgbFrame,
    VisionAssets,
};
use scene_motion::{scene_track, Thumb};

/// File name endings of videos in the footage folder.
const VIDEO_ENDINGS: [&str; 5] = ["mp4", "avi", "mkv", "mov", "webm"];

/// An identity jump: hips moving further than this fraction of the frame's longer side
/// between frames at most [`JUMP_SPAN`] apart.
const JUMP_FRACTION: f32 = 0.15;
const JUMP_SPAN: usize = 2;

/// rigcast's run over one clip.
struct Ours {
    width: f32,
    height: f32,
    /// Per frame, per slot: the output landmarks' image points when seen (smoothed, what a
    /// user gets, as MediaPipe's are by default).
    slots: Vec<Vec<Option<Points>>>,
    /// Per frame, where the scene has moved since the first frame (source pixels; see
    /// `scene_motion`).
    scene: Vec<Vec2>,
    fps: f64,
    /// CPU time a frame with decoding, and of it the decoder's, ms (see the module docs).
    cpu_ms: f64,
    decoder_ms: f64,
    detections: u64,
    /// Landmark model runs (crops).
    inferences: u64,
    /// Runs of the second-opinion model (left and right of a person read in doubt).
    second_opinions: u64,
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
    let mut source = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, 30.0).unwrap();
    // ffprobe has ended, ffmpeg not: the children's CPU from here on is the decoder's.
    let children_before = common::children_cpu_secs();
    // The clock starts after the first frame, as `bench_mediapipe.py`'s does for MediaPipe
    // (whose graph is built lazily on it): start-up is not the frame rate. So does this
    // process's CPU count; the decoder's counts whole on both sides.
    let mut started = None;
    let mut cpu_started = 0.0;
    // Landmarks come in the source's pixels; the frames are decoded smaller.
    let (decoded_width, decoded_height) = source.size();
    let mut frame = RgbFrame::default();
    let mut slots = Vec::new();
    let mut to_source = 1.0;
    // The judge's own measure of the scene's motion is kept out of the frame rate and CPU.
    let (mut thumbs, mut thumb_secs, mut thumb_cpu) = (Vec::new(), 0.0, 0.0);
    while max.is_none_or(|m| slots.len() < m) && source.next_frame(&mut frame).unwrap() {
        to_source = frame.source_from_frame;
        pipeline.process_frame(&frame).unwrap();
        slots.push(
            (0..pipeline.num_people())
                .map(|s| pipeline.person(s).map(points))
                .collect(),
        );
        let (thumb_started, thumb_cpu_started) = (Instant::now(), common::thread_cpu_secs());
        thumbs.push(Thumb::new(&frame.data, frame.width, frame.height));
        if started.is_some() {
            thumb_secs += thumb_started.elapsed().as_secs_f64();
            thumb_cpu += common::thread_cpu_secs() - thumb_cpu_started;
        }
        started.get_or_insert_with(|| {
            cpu_started = common::cpu_secs();
            Instant::now()
        });
    }
    let secs = started.map_or(0.0, |t| t.elapsed().as_secs_f64()) - thumb_secs;
    let cpu = common::cpu_secs() - cpu_started - thumb_cpu;
    // Dropping the source waits for ffmpeg (killed if frames were left).
    drop(source);
    let decoder_cpu = common::children_cpu_secs() - children_before;
    let timed = slots.len().saturating_sub(1).max(1) as f64;
    if let Some(dir) = std::env::var_os("RIGCAST_FOOTAGE_DUMP") {
        let name = path.file_name().unwrap().to_string_lossy();
        let file = Path::new(&dir).join(format!("{name}.{}.json", config.model.as_str()));
        std::fs::write(file, serde_json::to_string(&slots).unwrap()).unwrap();
    }
    let width = decoded_width as f32 * to_source;
    Ours {
        width,
        height: decoded_height as f32 * to_source,
        scene: scene_track(&thumbs, width),
        fps: slots.len().saturating_sub(1) as f64 / secs.max(1e-9),
        cpu_ms: 1e3 * (cpu + decoder_cpu) / timed,
        decoder_ms: 1e3 * decoder_cpu / timed,
        slots,
        detections: pipeline.stats().detections,
        inferences: pipeline.stats().inferences,
        second_opinions: pipeline.stats().second_opinions,
    }
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
/// longer side `side` in the picture (the measure, with `scene` empty), and, given
/// `scene` (where the scene has moved by each frame: see `scene_motion`), against it too. A
/// camera's whip carries everyone across the picture as fast as a jump to someone else would;
/// a track that stays with its person moves with the scene then, and one that jumps moves
/// against it.
fn jumps<'a>(frames: impl Iterator<Item = Option<&'a Points>>, scene: &[Vec2], side: f32) -> usize {
    let limit = JUMP_FRACTION * side;
    let hip: Vec<Option<Vec2>> = frames.map(|p| p.map(hips)).collect();
    let pan = |i: usize, j: usize| match (scene.get(i), scene.get(j)) {
        (Some(a), Some(b)) => *b - *a,
        _ => Vec2::ZERO,
    };
    (0..hip.len())
        .filter(|&i| {
            (1..=JUMP_SPAN).any(|d| {
                matches!((hip[i], hip.get(i + d).copied().flatten()),
                    (Some(a), Some(b)) if a.distance(b) > limit
                        && (b - a - pan(i, i + d)).length() > limit)
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
fn left_right(ours: &Ours, theirs: &MediaPipeRun) -> (usize, usize) {
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

/// MediaPipe's one person, followed through rigcast's slots: (frames MediaPipe sees someone,
/// those where some slot shows that person (shoulders within half their torso: the shoulders
/// are seen where the hips are often guesses, at a desk, in a close-up, below a table),
/// changes of the slot showing them). Person `#0`'s coverage says how often `#0` shows someone;
/// with two people in view, who is `#0` and who `#1` is the tracker's first choice, and a
/// change of the start path can swap them for a whole clip (a cook found first in `#1` while a
/// misreading holds `#0`). This says whether the person was kept, and in one identity: a change
/// is the person shown by another slot than before, the slot before not showing them (lost
/// and found again as someone else, or two slots traded). MediaPipe's own jumps (hips moving
/// more than [`JUMP_FRACTION`] of `side` from its last reading) start a new person, no change.
fn followed(ours: &Ours, theirs: &MediaPipeRun, side: f32) -> (usize, usize, usize) {
    let (mut seen, mut held, mut changes) = (0, 0, 0);
    let (mut slot, mut last_hips): (Option<usize>, Option<Vec2>) = (None, None);
    for (slots, mp) in ours.slots.iter().zip(&theirs.frames) {
        let Some(mp) = mp else { continue };
        seen += 1;
        let at = hips(mp);
        if last_hips.is_some_and(|h| h.distance(at) > JUMP_FRACTION * side) {
            slot = None;
        }
        last_hips = Some(at);
        let top = shoulders(mp);
        let reach = 0.5 * top.distance(at);
        let shows = |s: usize| {
            slots[s]
                .as_ref()
                .is_some_and(|p| shoulders(p).distance(top) <= reach)
        };
        let Some(first) = (0..slots.len()).find(|&s| shows(s)) else {
            continue;
        };
        held += 1;
        match slot {
            Some(s) if shows(s) => {}
            Some(_) => {
                changes += 1;
                slot = Some(first);
            }
            None => slot = Some(first),
        }
    }
    (seen, held, changes)
}

/// Frames where rigcast's `#0` shows someone and MediaPipe nobody. Coverage counts every
/// reading, and where the anchor sees nobody the judge has nothing to tell a person from a
/// misreading: a cook's hand filling the picture, read upside down as a body, counts as much as
/// a small player MediaPipe misses. MediaPipe asked about a crop around such a reading is no
/// referee either: it agrees with neither. So these frames are shown beside the coverage, and
/// the bound reads the coverage as the issue defines it.
fn unconfirmed(ours: &Ours, theirs: &MediaPipeRun) -> usize {
    ours.slots
        .iter()
        .zip(&theirs.frames)
        .filter(|(slots, mp)| slots.first().is_some_and(Option::is_some) && mp.is_none())
        .count()
}

fn percent(n: usize, of: usize) -> f64 {
    100.0 * n as f64 / of.max(1) as f64
}

/// Frames where the 3D reference (from the rig's other cameras) sees the person and rigcast's
/// `#0` is that person (hips within half a torso of the reference's projected hips): (such
/// frames, rigcast's labels the same way round as the reference's projection).
fn left_right_3d(ours: &Ours, rig: &Rig, camera: usize) -> (usize, usize) {
    let reference = rig.reference(Some(camera));
    let view = rig.view(camera);
    let (mut frames, mut agree) = (0, 0);
    for (i, slots) in ours.slots.iter().enumerate() {
        let f = usize::try_from(i as i64 - view.offset).ok();
        let (Some(us), Some(r)) = (&slots[0], f.and_then(|f| reference.get(f)?.as_ref())) else {
            continue;
        };
        let Some(projected) = r
            .joints
            .iter()
            .map(|&p| view.cam.project(view.video, p))
            .collect::<Option<Vec<DVec2>>>()
        else {
            continue;
        };
        let mid = |a: usize, b: usize| (projected[a] + projected[b]) * 0.5;
        let hips_at = mid(idx::LEFT_HIP, idx::RIGHT_HIP);
        let torso = mid(idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER).distance(hips_at);
        if hips(us).as_dvec2().distance(hips_at) > 0.5 * torso {
            continue;
        }
        frames += 1;
        agree += usize::from(reference3d::labels_agree(us, &projected, &rig.body));
    }
    (frames, agree)
}

/// What one clip's row compares rigcast with: MediaPipe on the same frames, and the 3D
/// reference where the clip is a camera of a calibrated rig.
struct Anchors<'a> {
    mediapipe: Result<PathBuf, String>,
    rig: Option<&'a Rig>,
}

/// The frame rate rigcast's is judged against (issue 32: "person count as in the clip"):
/// MediaPipe asked for as many people as the clip holds, up to as many as rigcast tracks.
struct SpeedAnchor {
    /// People in the clip as MediaPipe asked for up to `max_people` finds them (see
    /// [`MediaPipeCrowd::people`]); 1 without a second identity slot.
    people: usize,
    /// That run, when one was made.
    crowd: Option<MediaPipeCrowd>,
    /// MediaPipe asked for `people`: its one-person tracker for 1.
    fps: f64,
    cpu_ms: Option<f64>,
    decoder_ms: Option<f64>,
    cached: bool,
}

impl SpeedAnchor {
    /// The clip's people, how they were counted, and the anchor's frame rate.
    fn text(&self) -> String {
        match &self.crowd {
            None => format!("{} (-) | {:.1}", self.people, self.fps),
            Some(c) => format!(
                "{} (all {} in {:.0} %, {:.1} fps) | {:.1}",
                self.people,
                c.asked,
                c.all_found_percent(),
                c.fps,
                self.fps
            ),
        }
    }
}

/// The CPU a frame with decoding, ours against MediaPipe's (`speed`'s; `None` from a cache
/// written before the script printed it), each with its decoder's share in brackets (the two
/// decode differently: rigcast scaled to the model's size on one thread, MediaPipe at the
/// video's size), and their ratio: MediaPipe's over ours, as the frame rates' ratio is ours
/// over theirs. A cached anchor's CPU is from another run, often over every frame of the clip:
/// marked so, as it is read the same way at any load.
fn cpu_text(ours: &Ours, speed: &SpeedAnchor) -> String {
    let with_decoder = |total: f64, decoder: Option<f64>| match decoder {
        Some(d) => format!("{total:.1} ({d:.1})"),
        None => format!("{total:.1}"),
    };
    let mine = with_decoder(ours.cpu_ms, Some(ours.decoder_ms));
    match speed.cpu_ms {
        None => format!("{mine} / - | -"),
        Some(t) => format!(
            "{mine} / {} | {:.2}{}",
            with_decoder(t, speed.decoder_ms),
            t / ours.cpu_ms.max(1e-9),
            if speed.cached { " (cached)" } else { "" }
        ),
    }
}

/// The speed anchor of `clip` (see [`SpeedAnchor`]): MediaPipe asked for `max_people` counts
/// the people (its own multi-person tracker, independent of rigcast's); that run is the anchor
/// when it counts as many, MediaPipe asked for the count when fewer but two or more, and its
/// one-person tracker (`one`, the coverage anchor) for one.
fn speed_anchor(
    python: &Path,
    clip: &Path,
    max: Option<usize>,
    max_people: usize,
    one: &MediaPipeRun,
) -> SpeedAnchor {
    let single = |crowd| SpeedAnchor {
        people: 1,
        crowd,
        fps: one.fps,
        cpu_ms: one.cpu_ms,
        decoder_ms: one.decoder_ms,
        cached: one.cached,
    };
    if max_people < 2 {
        return single(None);
    }
    let crowd = run_mediapipe_crowd(python, clip, max, "full", max_people);
    let people = crowd.people();
    if people < 2 {
        return single(Some(crowd));
    }
    let (fps, cpu_ms, decoder_ms, cached) = if people == crowd.asked {
        (crowd.fps, crowd.cpu_ms, crowd.decoder_ms, crowd.cached)
    } else {
        let asked = run_mediapipe_crowd(python, clip, max, "full", people);
        (asked.fps, asked.cpu_ms, asked.decoder_ms, asked.cached)
    };
    SpeedAnchor {
        people,
        crowd: Some(crowd),
        fps,
        cpu_ms,
        decoder_ms,
        cached,
    }
}

/// One clip: its table row, and the bounds it misses. Panics if either program fails on it.
fn judge_clip(
    clip: &Path,
    config: &PipelineConfig,
    max: Option<usize>,
    anchors: &Anchors,
) -> (String, Vec<String>) {
    let name = clip.file_name().unwrap().to_string_lossy().into_owned();
    let ours = run_ours(clip, config, max);
    let n = ours.slots.len();
    assert!(n > 0, "{name}: no frame decoded");
    let slots = ours.slots.first().map_or(0, Vec::len);
    let coverage: Vec<f64> = (0..slots)
        .map(|s| percent(ours.slots.iter().filter(|f| f[s].is_some()).count(), n))
        .collect();
    let side = ours.width.max(ours.height);
    let slot_jumps = |scene: &[Vec2]| -> usize {
        (0..slots)
            .map(|s| jumps(ours.slots.iter().map(|f| f[s].as_ref()), scene, side))
            .sum()
    };
    // The bound is the measure (in the picture); against the scene is shown beside.
    let (our_jumps, our_scene_jumps) = (slot_jumps(&[]), slot_jumps(&ours.scene));
    let mut failures = Vec::new();
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
    let ours_text = format!("| {name} | {n} | {coverage_text} |",);
    let per_frame = |runs: u64| runs as f64 / n.max(1) as f64;
    let second = match ours.second_opinions {
        0 => String::new(),
        runs => format!(" + {:.2} second", per_frame(runs)),
    };
    let tail = format!(
        "{} | {:.2}{second} | {:.1} |",
        ours.detections,
        per_frame(ours.inferences),
        ours.fps
    );
    let Ok(python) = &anchors.mediapipe else {
        return (
            format!("{ours_text} - | - | {our_jumps}, {our_scene_jumps} (-) | - | {tail} - | - | - | - | - | {:.1} ({:.1}) / - | - |", ours.cpu_ms, ours.decoder_ms),
            failures,
        );
    };
    let theirs = run_mediapipe(python, clip, max);
    assert_eq!(
        theirs.frames.len(),
        n,
        "{name}: MediaPipe and rigcast read different frame counts"
    );
    let theirs_cov = percent(theirs.frames.iter().filter(|f| f.is_some()).count(), n);
    let camera = anchors
        .rig
        .and_then(|rig| Some((rig, rig.camera_of(clip)?)));
    let (reference, agree, against) = match camera {
        Some((rig, c)) => {
            let (r, a) = left_right_3d(&ours, rig, c);
            (r, a, "3D")
        }
        None => {
            let (r, a) = left_right(&ours, &theirs);
            (r, a, "MediaPipe")
        }
    };
    let speed = speed_anchor(python, clip, max, config.tracker.max_people, &theirs);
    let (mp_seen, mp_held, mp_changes) = followed(&ours, &theirs, side);
    let agreement = if reference > 0 {
        format!("{:.1}", percent(agree, reference))
    } else {
        "-".into()
    };
    let ratio = |fps: f64, cached: bool| {
        if cached {
            "- (cached)".into()
        } else {
            format!("{:.2}", ours.fps / fps)
        }
    };
    let row = format!(
        "{ours_text} {theirs_cov:.1} ({}) | {:.1}, {mp_changes} | {our_jumps}, {our_scene_jumps} ({}, {}) | {agreement} ({reference}, {against}) | {tail} {:.1} | {} | {} | {} | {} |",
        unconfirmed(&ours, &theirs),
        percent(mp_held, mp_seen),
        jumps(theirs.frames.iter().map(Option::as_ref), &[], side),
        jumps(theirs.frames.iter().map(Option::as_ref), &ours.scene, side),
        theirs.fps,
        speed.text(),
        ratio(theirs.fps, theirs.cached),
        ratio(speed.fps, speed.cached),
        cpu_text(&ours, &speed),
    );
    if coverage.first().copied().unwrap_or(0.0) < theirs_cov - 1.0 {
        failures.push(format!(
            "{name}: person #0 in {:.1} % of frames, MediaPipe {theirs_cov:.1} %",
            coverage[0]
        ));
    }
    if reference > 0 && percent(agree, reference) < 99.0 {
        failures.push(format!(
            "{name}: left/right as the {against} reference in {agree} of {reference} frames"
        ));
    }
    let ratio = ours.fps / speed.fps;
    if !cfg!(debug_assertions) && !speed.cached && ratio < 2.0 {
        failures.push(format!(
            "{name}: {ratio:.2}× the frame rate of MediaPipe for {}",
            speed.people
        ));
    }
    (row, failures)
}

/// The judge over every clip found: the table printed, the bounds missed returned.
fn judge() -> Vec<String> {
    let Some((assets, config)) = common::default_config_or_skip("vision_footage") else {
        return Vec::new();
    };
    let config = PipelineConfig {
        model: model(),
        ..config
    };
    let clips = clips(&assets);
    if clips.is_empty() {
        println!("SKIP vision_footage: no clips found");
        return Vec::new();
    }
    let mediapipe = mediapipe_python();
    if let Err(reason) = &mediapipe {
        println!("SKIP the comparison with MediaPipe: {reason}");
    }
    // The 3D reference is built only when a clip judged is one of its cameras.
    let pose2sim = assets.root.join("pose2sim");
    let rig = mediapipe.as_ref().ok().filter(|_| {
        reference3d::calibrated_cameras(&pose2sim)
            .is_some_and(|cams| cams.iter().any(|(_, v)| clips.contains(v)))
    });
    let rig = rig.and_then(|python| Rig::new(python, &pose2sim));
    let max = frames_per_clip();
    if cfg!(debug_assertions) {
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
    println!("| clip | frames | coverage per slot % | MediaPipe % (frames only #0 shows someone in) | MediaPipe's person: in a slot %, slot changes | jumps: in picture, against scene (MediaPipe's) | left/right % (frames, against) | detector runs | model runs / frame | fps | MediaPipe fps, one person | people in the clip (MediaPipe for {max_people}: all found in % of frames, fps) | MediaPipe fps for the clip's people | ratio to one person | ratio to the clip's people (the bound) | CPU ms a frame with decoding (of it the decoder's), rigcast / MediaPipe for the clip's people | CPU ratio, MediaPipe's ÷ rigcast's (the bound's, steadier at load) |", max_people = config.tracker.max_people);
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let anchors = Anchors {
        mediapipe,
        rig: rig.as_ref(),
    };
    let mut failures = Vec::new();
    for clip in &clips {
        let (row, missed) = judge_clip(clip, &config, max, &anchors);
        println!("{row}");
        failures.extend(missed);
    }
    println!(
        "load at the end {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    failures
}

/// The judge as a report (CI runs it, 60 frames per clip by default): the table in the log and
/// the clips outside issue 32's bounds listed. Asserted: both programs ran on every clip, read
/// the same frames and gave figures (a failure in either panics).
#[test]
fn footage_judge_reports_every_clip() {
    let failures = judge();
    if !failures.is_empty() {
        println!(
            "outside issue 32's bounds (asserted by the ignored acceptance test):\n{}",
            failures.join("\n")
        );
    }
}

/// Issue 32's bounds asserted on every clip (`scripts/bench-vision-footage.sh` runs it: release,
/// every frame, lite and full).
#[test]
#[ignore = "issue 32: the default tracker does not meet these bounds on every clip yet; scripts/bench-vision-footage.sh runs it"]
fn default_settings_keep_the_person_against_mediapipe_on_real_footage() {
    let failures = judge();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A standing body's 33 points around hips at `(x, 300)`, shoulders 100 px above them.
fn standing_at(x: f32) -> Points {
    let mut p = vec![[x, 250.0, 1.0]; 33];
    for i in [idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER] {
        p[i] = [x, 200.0, 1.0];
    }
    for i in [idx::LEFT_HIP, idx::RIGHT_HIP] {
        p[i] = [x, 300.0, 1.0];
    }
    p
}

/// A run of ours (`slots` per frame) and MediaPipe's (`frames`) on a 1000×600 picture, with
/// nothing else measured: what the judge's counting tests read.
fn synthetic_runs(
    slots: Vec<Vec<Option<Points>>>,
    frames: Vec<Option<Points>>,
) -> (Ours, MediaPipeRun) {
    let ours = Ours {
        width: 1000.0,
        height: 600.0,
        slots,
        scene: Vec::new(),
        fps: 0.0,
        cpu_ms: 0.0,
        decoder_ms: 0.0,
        detections: 0,
        inferences: 0,
        second_opinions: 0,
    };
    let theirs = MediaPipeRun {
        frames,
        world: Vec::new(),
        width: 1000.0,
        height: 600.0,
        fps: 0.0,
        cpu_ms: None,
        decoder_ms: None,
        cached: true,
    };
    (ours, theirs)
}

#[test]
fn mediapipes_person_is_followed_through_the_slots_that_show_them() {
    let run = |ours: Vec<Vec<Option<Points>>>, theirs: Vec<Option<Points>>| {
        let (ours, theirs) = synthetic_runs(ours, theirs);
        followed(&ours, &theirs, 1000.0)
    };
    // MediaPipe's person walks right 5 px a frame; #0 shows them for 4 frames, is lost for
    // 2, and they come back as #1 while #0 shows someone else: one change.
    let theirs: Vec<Option<Points>> = (0..10)
        .map(|i| Some(standing_at(100.0 + 5.0 * i as f32)))
        .collect();
    let ours: Vec<Vec<Option<Points>>> = (0..10)
        .map(|i| {
            let them = Some(standing_at(100.0 + 5.0 * i as f32));
            match i {
                0..=3 => vec![them, None],
                4..=5 => vec![None, None],
                _ => vec![Some(standing_at(600.0)), them],
            }
        })
        .collect();
    assert_eq!(run(ours.clone(), theirs.clone()), (10, 8, 1));
    // Found again in #0: no change.
    let mut back = ours.clone();
    for frame in back.iter_mut().skip(6) {
        frame.swap(0, 1);
    }
    assert_eq!(run(back, theirs.clone()), (10, 8, 0));
    // MediaPipe jumps to the other person (500 px, more than 15 % of the picture) while #1
    // shows them: MediaPipe's change, not ours.
    let mut jumped = theirs.clone();
    for frame in jumped.iter_mut().skip(6) {
        *frame = Some(standing_at(600.0));
    }
    let mut ours = ours;
    for frame in ours.iter_mut().skip(6) {
        frame.swap(0, 1);
    }
    assert_eq!(run(ours, jumped), (10, 8, 0));
}

#[test]
fn frames_where_only_rigcasts_first_slot_shows_someone_are_counted() {
    // #0 shows someone in frames 0-5, #1 in 6-9; MediaPipe in 0-2 and 8-9: #0 alone in 3-5.
    let slots = (0..10)
        .map(|i| {
            let someone = Some(standing_at(100.0));
            if i < 6 {
                vec![someone, None]
            } else {
                vec![None, someone]
            }
        })
        .collect();
    let frames = (0..10)
        .map(|i| (i < 3 || i >= 8).then(|| standing_at(100.0)))
        .collect();
    let (ours, theirs) = synthetic_runs(slots, frames);
    assert_eq!(unconfirmed(&ours, &theirs), 3);
}
