//! The 3D reference (issue 32, item 4), on every calibrated rig found: the pose2sim
//! single-person demo's four calibrated
//! cameras (`scripts/setup-vision.sh` installs the videos and `Calib.qca.txt`, found by
//! listing: a camera of the calibration is judged when a video named after it is beside it)
//! triangulated from MediaPipe Pose 0.10.14's 2D landmarks (full model, run on every camera in
//! this run) into a reference, then rigcast lite (the default), rigcast full and MediaPipe full
//! judged against it per camera on the same frames: 3D bone directions (the model's world
//! landmarks against the reference turned into the camera's axes), PA-MPJPE (after the best
//! similarity), jitter (the mean joint acceleration of the hip-centred 3D, mm per frame²) and
//! left/right labelling (the model's 2D labels against the reference projected into the
//! camera). Beside rigcast's output, the landmark models' own readings (no left/right guard,
//! no smoothing) show which way round the network itself reads each view, and MediaPipe with
//! its lite model (the network rigcast's default runs, with MediaPipe's crops, runtime and
//! smoothing around it) shows what of the default's distance from MediaPipe full is the
//! network's.
//!
//! The reference a camera is judged against is triangulated from the *other* three cameras
//! only, so no detector's reading of the judged view is in it; MediaPipe shares the landmark
//! network's lineage with rigcast (rigcast runs BlazePose's converted models) but not its
//! runtime, crops, tracker or smoothing, and the robust triangulation (`common/reference3d.rs`)
//! takes neither its left/right labels nor a single view's outliers on trust.
//!
//! Asserted (what the reference must be to judge anything; these hold today): every camera has
//! a reference on at least 80 % of its frames, the left-out camera's own MediaPipe landmarks
//! land within 15 % of the torso of the reference's projection (median: calibration, frame
//! offsets and the padded frames of cameras 1 and 2 all right), bone lengths steady (upper
//! arms, thighs, shins: coefficient of variation < 0.1), and every model gave figures on every
//! camera. Issue 32's bounds (rigcast's default at least as accurate as MediaPipe full on every
//! camera, less jittery, left/right right on 99 % of frames) are listed, and asserted with
//! `RIGCAST_FOOTAGE_ACCEPTANCE=1`. Needs MediaPipe (`scripts/setup-mediapipe.sh`); skips with
//! the reason without it. The geometry itself is proven on a synthetic rig written in the
//! calibration's own format (no footage needed): a known body comes back through padded,
//! distorted views, with a view read mirrored, with every view mirrored, and with one view's
//! wrist far off (left out of four views; not held from three); the frame offsets on a
//! synthetic walk seen by cameras started late and early.
//!
//! With `RIGCAST_REFERENCE3D_DUMP=DIR` the judge also writes what it judged to `DIR`, to trace
//! an error to its stage offline: per camera (named after its video) the reference and
//! MediaPipe full's readings ([`dump_reference`]), and per rigcast model the stages' input
//! and output on every frame ([`dump_frame`]).
//!
//! A second test judges every other calibrated rig of the shared data the same way (caliscope
//! calibrations: the desk set's four webcams), on the landmarks its cameras see; its
//! calibration reader and frame offsets are proven on a synthetic rig written in caliscope's
//! format.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/mediapipe.rs"]
mod mediapipe;
#[path = "common/multiview.rs"]
mod multiview;
#[path = "common/reference3d.rs"]
mod reference3d;
#[path = "common/shared_data.rs"]
mod shared_data;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use mediapipe::{mediapipe_python, run_mediapipe_model, MediaPipeRun, Points};
use multiview::{similarity_aligned, Camera};
use reference3d::{Body, Frame3d, Rig, View};
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, Landmarks, ModelKind, PipelineConfig, PosePipeline,
    RgbFrame,
};

/// Bones whose directions are judged: upper arms, forearms, thighs, shins, and the shoulder
/// and hip lines (which say which way the body faces).
const BONES: [(usize, usize); 10] = [
    (idx::LEFT_SHOULDER, idx::LEFT_ELBOW),
    (idx::RIGHT_SHOULDER, idx::RIGHT_ELBOW),
    (idx::LEFT_ELBOW, idx::LEFT_WRIST),
    (idx::RIGHT_ELBOW, idx::RIGHT_WRIST),
    (idx::LEFT_HIP, idx::LEFT_KNEE),
    (idx::RIGHT_HIP, idx::RIGHT_KNEE),
    (idx::LEFT_KNEE, idx::LEFT_ANKLE),
    (idx::RIGHT_KNEE, idx::RIGHT_ANKLE),
    (idx::RIGHT_SHOULDER, idx::LEFT_SHOULDER),
    (idx::RIGHT_HIP, idx::LEFT_HIP),
];

/// The bones of [`BONES`] whose ends `body` holds.
fn bones(body: &Body) -> Vec<(usize, usize)> {
    BONES
        .into_iter()
        .filter(|&(a, b)| body.holds(a) && body.holds(b))
        .collect()
}

/// Joints of PA-MPJPE and jitter: the limbs' that `body` holds.
fn joints(body: &Body) -> Vec<usize> {
    reference3d::LIMBS
        .into_iter()
        .filter(|&j| body.holds(j))
        .collect()
}

/// One model's reading of one frame: image points (source pixels, with visibility) and world
/// points (metres, camera axes: x right, y down, z away).
#[derive(Clone)]
struct Reading {
    image: Points,
    world: Vec<DVec3>,
}

fn readings_of_mediapipe(run: &MediaPipeRun) -> Vec<Option<Reading>> {
    run.frames
        .iter()
        .zip(&run.world)
        .map(|(image, world)| {
            Some(Reading {
                image: image.clone()?,
                world: world
                    .as_ref()?
                    .iter()
                    .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
                    .collect(),
            })
        })
        .collect()
}

/// What of rigcast's person `#0` is judged.
#[derive(Clone, Copy, PartialEq)]
enum Output {
    /// What a user gets (the default settings).
    Default,
    /// The landmark model's own readings: no left/right guard, before smoothing (which way
    /// round the model itself reads each frame).
    ModelsOwn,
}

/// rigcast's person `#0` over every frame of `path` with the default settings but `model`.
fn readings_of_rigcast(
    path: &Path,
    config: &PipelineConfig,
    model: ModelKind,
    output: Output,
) -> Vec<Option<Reading>> {
    let mut config = PipelineConfig {
        model,
        ..config.clone()
    };
    config.tracker.swap_guard = output == Output::Default;
    let mut pipeline = PosePipeline::new(&config).unwrap();
    let mut source = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut frame = RgbFrame::default();
    let mut out = Vec::new();
    let dump = dump_dir().filter(|_| output == Output::Default);
    let mut dumped = String::new();
    while source.next_frame(&mut frame).unwrap() {
        pipeline.process_frame(&frame).unwrap();
        let person = match output {
            Output::Default => pipeline.person(0),
            Output::ModelsOwn => pipeline.raw_person(0),
        };
        out.push(person.map(|lm| Reading {
            image: lm.image[..33].iter().map(|p| [p.x, p.y, p.w]).collect(),
            world: lm.world[..33].iter().map(|p| p.as_dvec3()).collect(),
        }));
        if dump.is_some() {
            let stages = pipeline.raw_person(0).zip(pipeline.person(0));
            dump_frame(&mut dumped, frame.time_secs, out.len() - 1, stages);
        }
    }
    if let Some(dir) = dump {
        let stem = path.file_stem().unwrap_or_default().to_string_lossy();
        std::fs::write(dir.join(format!("{stem}_{model:?}_def.txt")), dumped).unwrap();
    }
    out
}

/// The folder `RIGCAST_REFERENCE3D_DUMP` names, if any (see the module doc).
fn dump_dir() -> Option<PathBuf> {
    std::env::var_os("RIGCAST_REFERENCE3D_DUMP").map(PathBuf::from)
}

/// One frame of a model's dump, a line: its time (s), its index, 1 when person `#0` was seen
/// (0 and nothing more where not), the picture's size (px), then for each of the 39 landmarks
/// the stages' input (image x, y, z, visibility; world x, y, z) and their output (image x,
/// y, z; world x, y, z).
fn dump_frame(out: &mut String, time: f64, index: usize, stages: Option<(&Landmarks, &Landmarks)>) {
    let Some((input, output)) = stages else {
        writeln!(out, "{time} {index} 0").unwrap();
        return;
    };
    write!(
        out,
        "{time} {index} 1 {} {}",
        input.picture.x, input.picture.y
    )
    .unwrap();
    for i in 0..input.image.len() {
        let (a, w) = (input.image[i], input.world[i]);
        let (b, v) = (output.image[i], output.world[i]);
        write!(
            out,
            " {} {} {} {} {} {} {}",
            a.x, a.y, a.z, a.w, w.x, w.y, w.z
        )
        .unwrap();
        write!(out, " {} {} {} {} {} {}", b.x, b.y, b.z, v.x, v.y, v.z).unwrap();
    }
    out.push('\n');
}

/// Camera `c`'s reference in the dump: a line `offset N` (the camera's frame `f + N` is the
/// reference's frame `f`), then a line per reference frame: its index and, for each of the 33
/// landmarks, the reference in the camera's axes (metres, NaN where not held), MediaPipe
/// full's world landmarks and its image landmarks (x, y, visibility) on that camera's frame.
fn dump_reference(dir: &Path, rig: &Rig, c: usize, reference: &[Option<Frame3d>]) {
    let (cam, video) = &rig.cameras[c];
    let (run, offset) = (&rig.runs[c], rig.offsets[c]);
    let mut out = format!("offset {offset}\n");
    for (f, r) in reference.iter().enumerate() {
        let g = usize::try_from(f as i64 + offset).ok();
        let world = g.and_then(|g| run.world.get(g)?.as_ref());
        let image = g.and_then(|g| run.frames.get(g)?.as_ref());
        write!(out, "{f}").unwrap();
        for j in 0..33 {
            let p = r.as_ref().filter(|r| r.holds(j));
            let p = p.map_or(DVec3::NAN, |r| cam.rot * r.joints[j]);
            let w = world.map_or([f32::NAN; 3], |w| w[j]);
            let i = image.map_or([f32::NAN; 3], |i| i[j]);
            write!(out, " {} {} {} {} {} {}", p.x, p.y, p.z, w[0], w[1], w[2]).unwrap();
            write!(out, " {} {} {}", i[0], i[1], i[2]).unwrap();
        }
        out.push('\n');
    }
    let stem = video.file_stem().unwrap_or_default().to_string_lossy();
    std::fs::write(dir.join(format!("{stem}_ref.txt")), out).unwrap();
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// One row of the table: a model on a camera against the reference.
#[derive(Default)]
struct Scores {
    frames: usize,
    bone_deg: f64,
    pa_mpjpe_mm: f64,
    jitter_mm: f64,
    left_right: f64,
    /// Median distance of the limbs' image landmarks from the reference's projection, px.
    image_px: f64,
}

/// A model's readings of one camera against that camera's reference of `body` (timeline
/// frame `f` is the camera's frame `f + offset`).
fn score(
    readings: &[Option<Reading>],
    reference: &[Option<Frame3d>],
    body: &Body,
    view: &View,
) -> Scores {
    let (cam, video, offset) = (view.cam, view.video, view.offset);
    let (judged_bones, judged_joints) = (bones(body), joints(body));
    let mut s = Scores::default();
    let (mut bones, mut pa, mut lr, mut px) = (Vec::new(), Vec::new(), 0usize, Vec::new());
    let mut judged: Vec<Option<&Reading>> = Vec::new();
    for (f, r) in reference.iter().enumerate() {
        let g = f as i64 + offset;
        let reading = usize::try_from(g)
            .ok()
            .and_then(|g| readings.get(g)?.as_ref());
        let (Some(r), Some(m)) = (r, reading) else {
            judged.push(None);
            continue;
        };
        judged.push(Some(m));
        s.frames += 1;
        let in_cam: Vec<DVec3> = r.joints.iter().map(|&p| cam.rot * p).collect();
        for &(a, b) in judged_bones
            .iter()
            .filter(|&&(a, b)| r.holds(a) && r.holds(b))
        {
            let want = (in_cam[b] - in_cam[a]).normalize_or_zero();
            let got = (m.world[b] - m.world[a]).normalize_or_zero();
            bones.push(want.dot(got).clamp(-1.0, 1.0).acos().to_degrees());
        }
        if judged_joints.iter().all(|&j| r.holds(j)) {
            let from: Vec<DVec3> = judged_joints.iter().map(|&j| m.world[j]).collect();
            let to: Vec<DVec3> = judged_joints.iter().map(|&j| in_cam[j]).collect();
            let aligned = similarity_aligned(&from, &to);
            pa.push(mean(
                &aligned
                    .iter()
                    .zip(&to)
                    .map(|(a, b)| a.distance(*b) * 1000.0)
                    .collect::<Vec<_>>(),
            ));
        }
        let projected: Vec<DVec2> = r
            .joints
            .iter()
            .map(|&p| cam.project(video, p).unwrap_or(DVec2::splat(f64::NAN)))
            .collect();
        lr += usize::from(reference3d::labels_agree(&m.image, &projected, body));
        for &j in judged_joints.iter().filter(|&&j| r.holds(j)) {
            let at = DVec2::new(m.image[j][0].into(), m.image[j][1].into());
            px.push(at.distance(projected[j]));
        }
    }
    px.sort_by(f64::total_cmp);
    s.image_px = px.get(px.len() / 2).copied().unwrap_or(f64::NAN);
    s.bone_deg = mean(&bones);
    s.pa_mpjpe_mm = mean(&pa);
    s.jitter_mm = jitter(judged.iter().map(|r| r.map(|r| r.world.clone())), body);
    s.left_right = 100.0 * lr as f64 / s.frames.max(1) as f64;
    s
}

/// Mean joint acceleration of `body`'s limb points around its centre (the hips', or the
/// shoulders' without hips; mm per frame²) over runs of three consecutive frames.
fn jitter(frames: impl Iterator<Item = Option<Vec<DVec3>>>, body: &Body) -> f64 {
    let ((a, b), judged) = (body.centre(), joints(body));
    let centred: Vec<Option<Vec<DVec3>>> = frames
        .map(|f| {
            f.map(|p| {
                let centre = (p[a] + p[b]) * 0.5;
                judged.iter().map(|&j| p[j] - centre).collect()
            })
        })
        .collect();
    let mut acc = Vec::new();
    for w in centred.windows(3) {
        if let [Some(a), Some(b), Some(c)] = w {
            for j in 0..a.len() {
                acc.push((a[j] - 2.0 * b[j] + c[j]).length() * 1000.0);
            }
        }
    }
    mean(&acc)
}

/// Coefficient of variation of a bone's length over the reference's frames that hold it.
fn length_cv(reference: &[Option<Frame3d>], a: usize, b: usize) -> f64 {
    let l: Vec<f64> = reference
        .iter()
        .flatten()
        .filter(|r| r.holds(a) && r.holds(b))
        .map(|r| r.joints[a].distance(r.joints[b]))
        .collect();
    let m = mean(&l);
    (mean(&l.iter().map(|x| (x - m) * (x - m)).collect::<Vec<_>>())).sqrt() / m.max(1e-9)
}

#[test]
fn similarity_alignment_recovers_a_known_pose() {
    let from: Vec<DVec3> = (0..12)
        .map(|i| {
            let t = i as f64;
            DVec3::new(t.sin(), (t * 0.7).cos(), t * 0.1)
        })
        .collect();
    let rot = glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 2.5);
    let to: Vec<DVec3> = from
        .iter()
        .map(|p| rot * *p * 1.7 + DVec3::new(0.3, -2.0, 5.0))
        .collect();
    let aligned = similarity_aligned(&from, &to);
    for (a, b) in aligned.iter().zip(&to) {
        assert!(a.distance(*b) < 1e-9, "{a} against {b}");
    }
}

/// The reference's own checks on camera `c` (left out of it): how far MediaPipe's landmarks
/// in that camera land from the reference's projection (median, fraction of the torso; each
/// frame read with whichever labelling fits, since this checks the geometry, not the labels).
fn left_out_error(reference: &[Option<Frame3d>], view: &View, body: &Body) -> f64 {
    let mut errors = Vec::new();
    for (f, r) in reference.iter().enumerate() {
        let g = f as i64 + view.offset;
        let p = usize::try_from(g)
            .ok()
            .and_then(|g| view.frames.get(g)?.as_ref());
        let (Some(r), Some(p)) = (r, p) else { continue };
        let at = |i: usize| DVec2::new(p[i][0].into(), p[i][1].into());
        let torso = ((at(11) + at(12)) - (at(23) + at(24))).length() * 0.5;
        let projected: Vec<DVec2> = r
            .joints
            .iter()
            .map(|&q| view.cam.project(view.video, q).unwrap_or(DVec2::splat(1e9)))
            .collect();
        let cost = |m: fn(usize) -> usize| -> Vec<f64> {
            joints(body)
                .iter()
                .filter(|&&j| r.holds(j) && r.holds(m(j)))
                .map(|&j| at(j).distance(projected[m(j)]) / torso.max(1.0))
                .collect()
        };
        let (same, swapped) = (cost(|j| j), cost(reference3d::mirror));
        errors.extend(if mean(&same) <= mean(&swapped) {
            same
        } else {
            swapped
        });
    }
    errors.sort_by(f64::total_cmp);
    errors
        .get(errors.len() / 2)
        .copied()
        .unwrap_or(f64::INFINITY)
}

fn row(camera: &str, model: &str, s: &Scores) -> String {
    format!(
        "| {camera} | {model} | {} | {:.1} | {:.0} | {:.2} | {:.1} | {:.1} |",
        s.frames, s.bone_deg, s.pa_mpjpe_mm, s.jitter_mm, s.left_right, s.image_px
    )
}

/// Issue 32's bounds on one camera: rigcast's default (lite) at least as accurate as MediaPipe
/// and less jittery; left/right right on 99 % of frames with lite and full.
fn misses(camera: &str, lite: &Scores, full: &Scores, theirs: &Scores) -> Vec<String> {
    let mut out = less_accurate(camera, "lite", lite, theirs);
    if lite.jitter_mm >= theirs.jitter_mm {
        out.push(format!(
            "{camera}: lite's jitter {:.2} against MediaPipe's {:.2} mm/frame²",
            lite.jitter_mm, theirs.jitter_mm
        ));
    }
    out.extend(mislabelled(camera, lite, full));
    out
}

/// Where `model` is less accurate than MediaPipe full (`theirs`) on one camera: its bone
/// directions or its PA-MPJPE.
fn less_accurate(camera: &str, model: &str, ours: &Scores, theirs: &Scores) -> Vec<String> {
    let mut out = Vec::new();
    if ours.bone_deg > theirs.bone_deg {
        out.push(format!(
            "{camera}: {model}'s bone directions {:.1}° against MediaPipe's {:.1}°",
            ours.bone_deg, theirs.bone_deg
        ));
    }
    if ours.pa_mpjpe_mm > theirs.pa_mpjpe_mm {
        out.push(format!(
            "{camera}: {model}'s PA-MPJPE {:.0} mm against MediaPipe's {:.0} mm",
            ours.pa_mpjpe_mm, theirs.pa_mpjpe_mm
        ));
    }
    out
}

/// Where lite or full labels left and right right on fewer than 99 % of one camera's frames.
fn mislabelled(camera: &str, lite: &Scores, full: &Scores) -> Vec<String> {
    let mut out = Vec::new();
    for (model, s) in [("lite", lite), ("full", full)] {
        if s.left_right < 99.0 {
            out.push(format!(
                "{camera}: {model} labels left/right right on {:.1} % of frames",
                s.left_right
            ));
        }
    }
    out
}

/// The reference's summary over every camera.
fn print_reference(rig: &Rig) {
    let all = rig.reference(None);
    let kept: Vec<&Frame3d> = all.iter().flatten().collect();
    let mut residual: Vec<f64> = kept.iter().map(|r| r.residual_px).collect();
    residual.sort_by(f64::total_cmp);
    let at = |q: usize| {
        residual
            .get(residual.len() * q / 10)
            .copied()
            .unwrap_or(f64::NAN)
    };
    println!(
        "reference from MediaPipe full on {} cameras: frame offsets {:?} at {} fps; {} of {} \
         frames; reprojection error median {:.1} px (p90 {:.1}); frames where MediaPipe's \
         labels were mirrored, per camera: {:?}",
        rig.cameras.len(),
        rig.offsets,
        rig.fps,
        kept.len(),
        rig.frames,
        at(5),
        at(9),
        (0..rig.cameras.len())
            .map(|k| kept.iter().filter(|r| r.mirrored >> k & 1 == 1).count())
            .collect::<Vec<_>>()
    );
}

/// Camera `c`'s reference from the other cameras, its row, and what is wrong with it.
fn reference_row(rig: &Rig, c: usize) -> (Vec<Option<Frame3d>>, Option<String>) {
    let cam = &rig.cameras[c].0;
    let reference = rig.reference(Some(c));
    let covered = reference.iter().flatten().count();
    let left_out = left_out_error(&reference, &rig.view(c), &rig.body);
    let cv = [(11, 13), (12, 14), (23, 25), (24, 26), (25, 27), (26, 28)]
        .iter()
        .filter(|&&(a, b)| rig.body.holds(a) && rig.body.holds(b))
        .map(|&(a, b)| length_cv(&reference, a, b))
        .fold(0.0, f64::max);
    let ref_jitter = jitter(
        reference.iter().map(|r| {
            r.as_ref()
                .filter(|r| joints(&rig.body).iter().all(|&j| r.holds(j)))
                .map(|r| r.joints.iter().map(|&p| cam.rot * p).collect())
        }),
        &rig.body,
    );
    let judged = joints(&rig.body);
    let held = reference
        .iter()
        .flatten()
        .map(|r| judged.iter().filter(|&&j| r.holds(j)).count())
        .sum::<usize>() as f64
        / (covered * judged.len()).max(1) as f64;
    println!(
        "| {} | reference (the other cameras) | {covered} | MediaPipe's 2D here {:.1} % of the \
         torso off it | bone lengths cv <= {cv:.3} | {ref_jitter:.2} | limbs held {:.1} % | - |",
        cam.name,
        left_out * 100.0,
        held * 100.0
    );
    let broken =
        ((covered as f64) < 0.8 * rig.frames as f64 || left_out > 0.15 || cv > 0.15).then(|| {
            format!(
                "{}: reference on {covered} of {} frames, MediaPipe {:.1} % of the torso off \
                 it, bone length cv {cv:.3}",
                cam.name,
                rig.frames,
                left_out * 100.0
            )
        });
    (reference, broken)
}

/// The table's header.
fn print_header() {
    println!(
        "| camera | model | frames | bone direction ° | PA-MPJPE mm | jitter mm/frame² | left/right % | 2D px |"
    );
    println!("|---|---|---|---|---|---|---|---|");
}

/// What one camera of a rig reads, per model judged.
struct CameraScores {
    name: String,
    lite: Scores,
    full: Scores,
    theirs: Scores,
}

/// Every camera of `rig` judged (the models' own readings too when `own`): the table's rows
/// printed, each camera's scores, and what is wrong with the reference or a row.
fn judge_rig(
    rig: &Rig,
    config: &PipelineConfig,
    python: &Path,
    own: bool,
) -> (Vec<CameraScores>, Vec<String>) {
    print_reference(rig);
    print_header();
    let (mut cameras, mut broken) = (Vec::new(), Vec::new());
    for (c, (cam, video)) in rig.cameras.iter().enumerate() {
        let (reference, wrong) = reference_row(rig, c);
        broken.extend(wrong);
        if let Some(dir) = dump_dir() {
            dump_reference(&dir, rig, c, &reference);
        }
        let view = rig.view(c);
        let judge = |readings: &[Option<Reading>]| score(readings, &reference, &rig.body, &view);
        let ours = |model, output| judge(&readings_of_rigcast(video, config, model, output));
        let lite = ours(ModelKind::Lite, Output::Default);
        let full = ours(ModelKind::Full, Output::Default);
        let theirs = judge(&readings_of_mediapipe(&rig.runs[c]));
        let their_lite = run_mediapipe_model(python, video, None, "lite");
        let their_lite = judge(&readings_of_mediapipe(&their_lite));
        let mut rows = vec![("rigcast lite (default)", &lite), ("rigcast full", &full)];
        let owns = own.then(|| {
            (
                ours(ModelKind::Lite, Output::ModelsOwn),
                ours(ModelKind::Full, Output::ModelsOwn),
            )
        });
        if let Some((lite_own, full_own)) = &owns {
            rows.push(("lite model's own readings", lite_own));
            rows.push(("full model's own readings", full_own));
        }
        rows.push(("MediaPipe full", &theirs));
        rows.push(("MediaPipe lite", &their_lite));
        for (model, s) in rows {
            println!("{}", row(&cam.name, model, s));
            if s.frames == 0 {
                broken.push(format!("{}: no frames judged for {model}", cam.name));
            }
        }
        cameras.push(CameraScores {
            name: cam.name.clone(),
            lite,
            full,
            theirs,
        });
    }
    (cameras, broken)
}

#[test]
fn pose2sim_3d_reference_judges_each_camera_and_model() {
    let Some((assets, config)) = common::default_config_or_skip("vision_reference3d") else {
        return;
    };
    let python = match mediapipe_python() {
        Ok(p) => p,
        Err(reason) => {
            println!("SKIP vision_reference3d: {reason}");
            return;
        }
    };
    let dir = assets.root.join("pose2sim");
    let Some(rig) = Rig::new(&python, &dir) else {
        println!(
            "SKIP vision_reference3d: no calibration with 3+ cameras' videos in {}",
            dir.display()
        );
        return;
    };
    let (cameras, broken) = judge_rig(&rig, &config, &python, true);
    assert!(broken.is_empty(), "{}", broken.join("\n"));
    let missed: Vec<String> = cameras
        .iter()
        .flat_map(|c| misses(&c.name, &c.lite, &c.full, &c.theirs))
        .collect();
    if std::env::var("RIGCAST_FOOTAGE_ACCEPTANCE").as_deref() == Ok("1") {
        assert!(missed.is_empty(), "{}", missed.join("\n"));
    } else if !missed.is_empty() {
        println!(
            "outside issue 32's bounds (asserted with RIGCAST_FOOTAGE_ACCEPTANCE=1):\n{}",
            missed.join("\n")
        );
    }
}

/// Every other calibrated rig of the shared data (caliscope's `camera_array.toml` under
/// `video/`, its cameras' videos found by listing, their frame offsets from its
/// `timestamps.csv`: the desk set's four webcams today, 6 fps) judged as the pose2sim rig is,
/// on the landmarks its cameras see (the desk set's seated man: nose, shoulders, elbows,
/// wrists; bones: upper arms, forearms, shoulder line; jitter around the shoulders).
///
/// Asserted beside the reference's own checks (what holds today): rigcast full at least as
/// accurate as MediaPipe full on every camera of every set (bone directions and PA-MPJPE),
/// and left/right right on 99 % of frames with lite and full. Issue 32's bounds on the
/// default (lite at least as accurate as MediaPipe full, less jittery) are listed, and
/// asserted with `RIGCAST_FOOTAGE_ACCEPTANCE=1`; they do not all hold: on the desk set (debug
/// build, MediaPipe cached, models with heatmaps) lite's bone directions / PA-MPJPE read
/// 16.4° / 53, 20.8 / 73, 10.5 / 39, 14.5 / 46 mm on cameras 0-3 against MediaPipe full's
/// 27.1 / 77, 19.4 / 68, 20.2 / 73, 21.8 / 77 (camera 1, a side view, outside); its jitter
/// at 6 fps, 23.9, 13.2, 10.0, 12.2 mm/frame² against 28.2, 17.2, 17.6, 15.6, is inside.
#[test]
fn calibrated_rigs_3d_reference_judges_each_camera() {
    let Some((_, config)) = common::default_config_or_skip("vision_reference3d") else {
        return;
    };
    let python = match mediapipe_python() {
        Ok(p) => p,
        Err(reason) => {
            println!("SKIP calibrated rigs: {reason}");
            return;
        }
    };
    let root = shared_data::shared_data_root().join("video");
    let sets = reference3d::caliscope_sets(&root);
    if sets.is_empty() {
        println!(
            "SKIP calibrated rigs: no caliscope calibration with 3+ cameras' videos under {}",
            root.display()
        );
        return;
    }
    let (mut broken, mut missed, mut listed) = (Vec::new(), Vec::new(), Vec::new());
    for set in sets {
        let name = set.name;
        let rig = Rig::of(&python, set.cameras, set.offsets);
        println!(
            "\n{name}: {} cameras, landmarks judged {:?}",
            rig.cameras.len(),
            rig.body.joints
        );
        let (cameras, wrong) = judge_rig(&rig, &config, &python, false);
        broken.extend(wrong.into_iter().map(|w| format!("{name} {w}")));
        for c in &cameras {
            let at = format!("{name} {}", c.name);
            missed.extend(less_accurate(&at, "full", &c.full, &c.theirs));
            missed.extend(mislabelled(&at, &c.lite, &c.full));
            listed.extend(misses(&at, &c.lite, &c.full, &c.theirs));
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
    assert!(missed.is_empty(), "{}", missed.join("\n"));
    if std::env::var("RIGCAST_FOOTAGE_ACCEPTANCE").as_deref() == Ok("1") {
        assert!(listed.is_empty(), "{}", listed.join("\n"));
    } else if !listed.is_empty() {
        println!(
            "outside issue 32's bounds (asserted with RIGCAST_FOOTAGE_ACCEPTANCE=1):\n{}",
            listed.join("\n")
        );
    }
}

/// A Qualisys export of cameras at `positions` (metres) looking at `target`, world z up, a
/// 1088×1920 portrait picture with mild distortion: the file's own conventions (rows of the
/// camera's axes with y up and z backwards, mm, 1/64 pixel), written from known geometry.
fn synthetic_qca(positions: &[DVec3], target: DVec3) -> String {
    let mut text = String::from("<calibration><cameras>\n");
    for (k, &pos) in positions.iter().enumerate() {
        // OpenCV axes: z forward, y down, x = y × z; the file keeps y up and z backwards.
        let z = (target - pos).normalize();
        let y = (DVec3::NEG_Z - z * DVec3::NEG_Z.dot(z)).normalize();
        let x = y.cross(z);
        let rows = [x, -y, -z];
        let r = |i: usize, j: usize| rows[i - 1][j - 1];
        text += &format!(
            "<camera active=\"1\" serial=\"c{k}\"><fov_video bottom=\"1919\" left=\"0\" right=\"1087\" top=\"0\"/>\
             <transform r11=\"{}\" r12=\"{}\" r13=\"{}\" r21=\"{}\" r22=\"{}\" r23=\"{}\" r31=\"{}\" r32=\"{}\" r33=\"{}\" x=\"{}\" y=\"{}\" z=\"{}\"/>\
             <intrinsic centerPointU=\"{}\" centerPointV=\"{}\" focalLengthU=\"{}\" focalLengthV=\"{}\" radialDistortion1=\"-0.05\" radialDistortion2=\"0.14\" tangentalDistortion1=\"0.0006\" tangentalDistortion2=\"0.0007\"/></camera>\n",
            r(1, 1), r(1, 2), r(1, 3), r(2, 1), r(2, 2), r(2, 3), r(3, 1), r(3, 2), r(3, 3),
            pos.x * 1000.0, pos.y * 1000.0, pos.z * 1000.0,
            540.0 * 64.0, 965.0 * 64.0, 1680.0 * 64.0, 1681.0 * 64.0,
        );
    }
    text + "</cameras></calibration>\n"
}

/// A standing body facing +y (its left towards -x), z up: the reference's landmarks, metres.
fn synthetic_body() -> Vec<DVec3> {
    let mut p = vec![DVec3::new(0.0, 0.1, 1.65); 33]; // the face: in front of the shoulders
    for (left, right, at) in [
        (11, 12, DVec3::new(0.2, 0.0, 1.5)),
        (13, 14, DVec3::new(0.25, 0.0, 1.2)),
        (15, 16, DVec3::new(0.25, 0.1, 0.95)),
        (23, 24, DVec3::new(0.1, 0.0, 1.0)),
        (25, 26, DVec3::new(0.1, 0.05, 0.55)),
        (27, 28, DVec3::new(0.1, 0.0, 0.1)),
    ] {
        p[left] = DVec3::new(-at.x, at.y, at.z);
        p[right] = at;
    }
    p
}

/// Four cameras around the synthetic body, their videos (1080 wide for the first two: the
/// calibrated picture padded), and each view's landmarks of `body` in one frame, the views
/// in `mirrored` with left and right exchanged.
fn synthetic_views(
    body: &[DVec3],
    mirrored: u32,
) -> (Vec<Camera>, Vec<DVec2>, Vec<Vec<Option<Points>>>) {
    let positions: Vec<DVec3> = (0..4)
        .map(|k| {
            let a = 0.6 + f64::from(k) * 1.3;
            DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 1.8)
        })
        .collect();
    let cameras =
        multiview::read_qca(&synthetic_qca(&positions, DVec3::new(0.0, 0.0, 1.0))).unwrap();
    let videos: Vec<DVec2> = (0..4)
        .map(|k| {
            if k < 2 {
                DVec2::new(1080.0, 1920.0)
            } else {
                DVec2::new(1088.0, 1920.0)
            }
        })
        .collect();
    let frames = cameras
        .iter()
        .zip(&videos)
        .enumerate()
        .map(|(k, (cam, &video))| {
            let label = |j: usize| {
                if mirrored >> k & 1 == 1 {
                    reference3d::mirror(j)
                } else {
                    j
                }
            };
            let points = (0..33)
                .map(|j| {
                    let px = cam.project(video, body[label(j)]).unwrap();
                    [px.x as f32, px.y as f32, 1.0]
                })
                .collect();
            vec![Some(points)]
        })
        .collect();
    (cameras, videos, frames)
}

fn views<'a>(
    cameras: &'a [Camera],
    videos: &[DVec2],
    frames: &'a [Vec<Option<Points>>],
) -> Vec<View<'a>> {
    cameras
        .iter()
        .zip(videos)
        .zip(frames)
        .map(|((cam, &video), frames)| View {
            cam,
            video,
            frames,
            offset: 0,
        })
        .collect()
}

#[test]
fn triangulation_recovers_a_known_body_through_padded_and_distorted_views() {
    let body = synthetic_body();
    let (cameras, videos, frames) = synthetic_views(&body, 0);
    // Projection and its inverse agree through the padding and the distortion.
    for (cam, &video) in cameras.iter().zip(&videos) {
        let px = cam.project(video, body[15]).unwrap();
        let ray = cam.ray(video, px);
        let c = cam.to_camera(body[15]);
        assert!(
            ray.distance(c.truncate() / c.z) < 1e-9,
            "{}: {ray}",
            cam.name
        );
    }
    let r = reference3d::frame(&views(&cameras, &videos, &frames), 0).unwrap();
    for &j in &reference3d::BODY {
        assert!(
            r.joints[j].distance(body[j]) < 1e-6,
            "joint {j}: {} against {}",
            r.joints[j],
            body[j]
        );
    }
    assert!(r.residual_px < 1e-3 && r.mirrored == 0, "{r:?}");
}

#[test]
fn the_reference_takes_sides_from_the_body_not_from_the_views_labels() {
    let body = synthetic_body();
    // One view mirrored: found and read the other way round. Every view mirrored: the
    // triangulation is the mirror image's, and the face puts the sides back.
    for mirrored in [0b0100, 0b1111] {
        let (cameras, videos, frames) = synthetic_views(&body, mirrored);
        let r = reference3d::frame(&views(&cameras, &videos, &frames), 0).unwrap();
        assert_eq!(r.mirrored, mirrored, "views read mirrored");
        for &j in &reference3d::BODY {
            assert!(
                r.joints[j].distance(body[j]) < 1e-6,
                "mirrored {mirrored:b}, joint {j}"
            );
        }
    }
    // One view's left wrist 150 px off: that view is left out of the wrist.
    let (cameras, videos, mut frames) = synthetic_views(&body, 0);
    frames[1][0].as_mut().unwrap()[15][0] += 150.0;
    let r = reference3d::frame(&views(&cameras, &videos, &frames), 0).unwrap();
    assert!(
        r.joints[15].distance(body[15]) < 1e-6,
        "wrist at {}",
        r.joints[15]
    );
    assert!(r.holds(15));
    // From three views (a least-squares point spreads a 150 px miss over all three, under the
    // rejection; 400 px is not), which one is off is not known: the wrist is not held, the
    // rest is.
    frames[1][0].as_mut().unwrap()[15][0] += 250.0;
    let three = views(&cameras[..3], &videos[..3], &frames[..3]);
    let r = reference3d::frame(&three, 0).unwrap();
    assert!(!r.holds(15) && r.holds(16) && r.holds(13), "{:b}", r.held);
}

/// A caliscope `camera_array.toml` of cameras at `positions` looking at `target` (z up, a
/// 1280×720 picture, strong barrel distortion with k3), and the same cameras as a Qualisys
/// export would give them, for comparing projections.
fn synthetic_caliscope(positions: &[DVec3], target: DVec3) -> String {
    let mut text = String::new();
    for (k, &pos) in positions.iter().enumerate() {
        let z = (target - pos).normalize();
        let y = (DVec3::NEG_Z - z * DVec3::NEG_Z.dot(z)).normalize();
        let x = y.cross(z);
        let t = -DVec3::new(x.dot(pos), y.dot(pos), z.dot(pos));
        let row = |v: DVec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
        text += &format!(
            "[cameras.{k}]\ncam_id = {k}\nignore = false\nsize = [1280, 720]\n\
             matrix = [[900.0, 0.0, 630.0], [0.0, 905.0, 370.0], [0.0, 0.0, 1.0]]\n\
             distortions = [-0.33, 0.046, -0.004, 0.004, 0.067]\n\
             translation = [{}, {}, {}]\nrotation = [{}, {}, {}]\n\n",
            t.x,
            t.y,
            t.z,
            row(x),
            row(y),
            row(z)
        );
    }
    text
}

#[test]
fn a_caliscope_rig_triangulates_a_known_body_through_its_distortion() {
    let body = synthetic_body();
    let positions: Vec<DVec3> = (0..3)
        .map(|k| {
            let a = 1.0 + f64::from(k) * 0.5;
            DVec3::new(1.0 * a.cos(), 1.0 * a.sin(), 1.4)
        })
        .collect();
    let cameras =
        multiview::read_caliscope(&synthetic_caliscope(&positions, DVec3::new(0.0, 0.0, 1.2)))
            .unwrap();
    assert_eq!(cameras.len(), 3);
    let video = DVec2::new(1280.0, 720.0);
    for (cam, &pos) in cameras.iter().zip(&positions) {
        assert!(cam.pos.distance(pos) < 1e-9, "{}: at {}", cam.name, cam.pos);
        assert!(
            cam.up().distance(DVec3::Z) < 0.5,
            "{}: up {}",
            cam.name,
            cam.up()
        );
        // Off-centre points, where the barrel bends most, come back through the inverse.
        for &j in &[11, 15, 16] {
            let px = cam.project(video, body[j]).unwrap();
            let c = cam.to_camera(body[j]);
            assert!(
                cam.ray(video, px).distance(c.truncate() / c.z) < 1e-7,
                "{}",
                cam.name
            );
        }
    }
    let frames: Vec<Vec<Option<Points>>> = cameras
        .iter()
        .map(|cam| {
            let points = (0..33)
                .map(|j| {
                    let px = cam.project(video, body[j]).unwrap();
                    [px.x as f32, px.y as f32, 1.0]
                })
                .collect();
            vec![Some(points)]
        })
        .collect();
    let videos = vec![video; 3];
    let r = reference3d::frame(&views(&cameras, &videos, &frames), 0).unwrap();
    for &j in &reference3d::BODY {
        assert!(r.joints[j].distance(body[j]) < 1e-3, "joint {j}");
    }
}

/// The synthetic body at time `t` (frames): still but for frames 20-35, where it steps along
/// x and its arms and legs swing at different paces (a clip's few quick moments are what
/// tell its cameras' offsets).
fn synthetic_body_at(t: f64) -> Vec<DVec3> {
    let mut body = synthetic_body();
    let t = t.clamp(20.0, 35.0);
    let step = DVec3::new(0.004 * t, 0.0, 0.0);
    // (landmark, swing a frame in radians, reach in metres); the right side 1.3× as quick.
    for (j, pace, reach) in [
        (13, 0.21, 0.1),
        (15, 0.21, 0.25),
        (25, 0.13, 0.08),
        (27, 0.13, 0.2),
    ] {
        for (j, pace) in [(j, pace), (reference3d::mirror(j), pace * 1.3)] {
            body[j].y += reach * (pace * t).sin();
            body[j].z += 0.5 * reach * (pace * t).cos();
        }
    }
    body.iter().map(|&p| p + step).collect()
}

#[test]
fn synchronise_finds_cameras_that_started_late_or_early() {
    // Camera k's frame g shows the body at time g - late[k]: its offset is late[k].
    let late = [0i64, 0, 3, -2];
    let (cameras, videos, _) = synthetic_views(&synthetic_body(), 0);
    let frames: Vec<Vec<Option<Points>>> = (0..4)
        .map(|k| {
            (0..60)
                .map(|g| {
                    let body = synthetic_body_at((g - late[k]) as f64);
                    // A steady ±2 px of noise a landmark, as a detector's.
                    let noise = |j: usize, axis: usize| {
                        let n = (g as usize * 131 + j * 17 + axis * 7 + k * 3) * 7919 % 101;
                        (n as f32 / 100.0 - 0.5) * 4.0
                    };
                    let points = body
                        .iter()
                        .enumerate()
                        .map(|(j, &p)| {
                            let px = cameras[k].project(videos[k], p).unwrap();
                            [px.x as f32 + noise(j, 0), px.y as f32 + noise(j, 1), 1.0]
                        })
                        .collect();
                    Some(points)
                })
                .collect()
        })
        .collect();
    let mut rig = views(&cameras, &videos, &frames);
    reference3d::synchronise(&mut rig, 60, 30.0, &Body::whole());
    let found: Vec<i64> = rig.iter().map(|v| v.offset).collect();
    assert_eq!(found, late);
}

#[test]
fn caliscope_frame_times_give_each_cameras_offset() {
    let cams: Vec<(multiview::Camera, std::path::PathBuf)> = multiview::read_caliscope(
        &synthetic_caliscope(&[DVec3::X, DVec3::Y, DVec3::NEG_X], DVec3::ZERO),
    )
    .unwrap()
    .into_iter()
    .map(|c| (c, std::path::PathBuf::new()))
    .collect();
    let rows = |starts: [i64; 3], drop: Option<(i64, i64)>| {
        let mut text = String::from("sync_index,cam_id,frame_index,frame_time\n");
        for sync in 10..20 {
            for (k, &start) in starts.iter().enumerate() {
                if sync >= start && drop != Some((k as i64, sync)) {
                    text += &format!("{sync},{k},{sync},{}.0\n", sync);
                }
            }
        }
        text
    };
    // Camera 1 starts two frames late: its first frame is the set's frame 2.
    assert_eq!(
        reference3d::caliscope_offsets(&rows([10, 12, 10], None), &cams),
        Some(vec![0, -2, 0])
    );
    // A dropped frame breaks the one-for-one order: left to the search.
    assert_eq!(
        reference3d::caliscope_offsets(&rows([10, 10, 10], Some((2, 15))), &cams),
        None
    );
}
