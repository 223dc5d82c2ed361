//! A 3D reference of one person from several calibrated views' 2D landmarks (another program's:
//! the tests give it MediaPipe's), robust to what such landmarks get wrong:
//! - a view that reads the person mirrored (left and right swapped, whole or in part of the
//!   clip): every labelling of the views is tried and the one whose triangulation reprojects
//!   best is kept, per frame;
//! - a wrong joint in one view: with three views or more, a view whose reprojection of a joint
//!   misses by more than [`REJECT`] of the person's torso there is left out for that joint;
//! - which side is the body's left then comes from the body, not from any view's labels: the
//!   face (nose) is in front, and the body's left is on its left (left × up = forward);
//! - cameras that did not start together: each camera's frame offset is the one whose
//!   triangulation reprojects best (searched within [`MAX_SHIFT_SECS`]).
//!
//! Each view's landmarks count by their visibility. Needs `common/mediapipe.rs` and
//! `common/multiview.rs` included beside it as `mediapipe` and `multiview`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{FfmpegSource, FrameSource};

use crate::mediapipe::{run_mediapipe, MediaPipeRun, Points};
use crate::multiview::{read_qca, triangulate, Camera};

/// The landmarks the reference holds: the nose (which way the body faces) and the limbs.
pub const BODY: [usize; 13] = [
    idx::NOSE,
    idx::LEFT_SHOULDER,
    idx::RIGHT_SHOULDER,
    idx::LEFT_ELBOW,
    idx::RIGHT_ELBOW,
    idx::LEFT_WRIST,
    idx::RIGHT_WRIST,
    idx::LEFT_HIP,
    idx::RIGHT_HIP,
    idx::LEFT_KNEE,
    idx::RIGHT_KNEE,
    idx::LEFT_ANKLE,
    idx::RIGHT_ANKLE,
];

/// A view's reprojection of a joint missing by more than this fraction of the torso (in that
/// view) leaves the view out for that joint, when three views or more see it.
pub const REJECT: f64 = 0.2;
/// A frame is a reference when its median reprojection error is within this fraction of the
/// torso.
pub const ACCEPT: f64 = 0.1;
/// At most this many views make a frame.
pub const MAX_VIEWS: usize = 8;
/// Camera offsets are searched within this many seconds either way.
pub const MAX_SHIFT_SECS: f64 = 0.2;

/// The same landmark on the other side (BlazePose's 33: odd is left from the shoulders down).
pub fn mirror(i: usize) -> usize {
    match i {
        0 => 0,
        1..=3 => i + 3,
        4..=6 => i - 3,
        7 | 9 => i + 1,
        8 | 10 => i - 1,
        _ if i % 2 == 1 => i + 1,
        _ => i - 1,
    }
}

/// One camera's 2D landmarks: `frames[f + offset]` is the reference's frame `f`.
pub struct View<'a> {
    pub cam: &'a Camera,
    /// The video's size in pixels.
    pub video: DVec2,
    pub frames: &'a [Option<Points>],
    pub offset: i64,
}

/// One view's observation of a frame, in normalised image coordinates.
struct Seen<'a> {
    cam: &'a Camera,
    rays: Vec<DVec2>,
    weights: Vec<f64>,
    /// Pixels per normalised unit, and the torso in pixels.
    ppu: f64,
    torso: f64,
}

/// The reference at one frame.
#[derive(Clone, Debug)]
pub struct Frame3d {
    /// World positions (metres) of the [`BODY`] landmarks, indexed by landmark (others zero).
    pub joints: Vec<DVec3>,
    /// Median reprojection error over the views and joints kept, pixels.
    pub residual_px: f64,
    /// The same as a fraction of the torso.
    pub residual_torso: f64,
    /// Views whose labels were read mirrored (bit per view).
    pub mirrored: u32,
}

fn seen<'a>(view: &View<'a>, f: i64) -> Option<Seen<'a>> {
    let g = usize::try_from(f + view.offset).ok()?;
    let p = view.frames.get(g)?.as_ref()?;
    let px = |i: usize| DVec2::new(f64::from(p[i][0]), f64::from(p[i][1]));
    let mid = |a: usize, b: usize| (px(a) + px(b)) * 0.5;
    let torso =
        mid(idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER).distance(mid(idx::LEFT_HIP, idx::RIGHT_HIP));
    Some(Seen {
        cam: view.cam,
        rays: (0..p.len())
            .map(|i| view.cam.ray(view.video, px(i)))
            .collect(),
        weights: p.iter().map(|q| f64::from(q[2]).clamp(0.05, 1.0)).collect(),
        ppu: view.cam.pixels_per_unit(view.video),
        torso: torso.max(1.0),
    })
}

fn error_px(s: &Seen, p: DVec3, ray: DVec2) -> f64 {
    let c = s.cam.to_camera(p);
    if c.z <= 1e-6 {
        return f64::INFINITY;
    }
    (c.truncate() / c.z).distance(ray) * s.ppu
}

/// One joint from the views (each read mirrored when its bit is set), one view left out when
/// it misses by more than [`REJECT`]: the point and each kept view's error / torso.
fn joint(seen: &[Seen], mirrored: u32, j: usize, reject: bool) -> Option<(DVec3, Vec<(f64, f64)>)> {
    let label = |k: usize| if mirrored >> k & 1 == 1 { mirror(j) } else { j };
    let mut kept: Vec<usize> = (0..seen.len()).collect();
    loop {
        let rays: Vec<_> = kept
            .iter()
            .map(|&k| {
                (
                    seen[k].rays[label(k)],
                    seen[k].weights[label(k)],
                    seen[k].cam,
                )
            })
            .collect();
        let p = triangulate(&rays)?;
        let errors: Vec<(usize, f64)> = kept
            .iter()
            .map(|&k| (k, error_px(&seen[k], p, seen[k].rays[label(k)])))
            .collect();
        let &(worst, err) = errors.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
        if reject && kept.len() >= 3 && err > REJECT * seen[worst].torso {
            kept.retain(|&k| k != worst);
            continue;
        }
        let e = errors
            .iter()
            .map(|&(k, e)| (e, e / seen[k].torso))
            .collect();
        return Some((p, e));
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::INFINITY;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The reference at frame `f` from the views that see it (at least two), or `None`.
pub fn frame(views: &[View], f: i64) -> Option<Frame3d> {
    // Every labelling is tried: 2^(views - 1) of them, so a larger rig counts its first ones.
    let seen: Vec<Seen> = views
        .iter()
        .filter_map(|v| seen(v, f))
        .take(MAX_VIEWS)
        .collect();
    if seen.len() < 2 {
        return None;
    }
    // The labelling is chosen on every view (with a view left out per joint, two views would
    // agree with any labelling); the first view's labels fixed: the other labellings are
    // these mirrored as a whole.
    let labelling = |mirrored: u32, reject: bool| -> Option<Frame3d> {
        let mut joints = vec![DVec3::ZERO; 33];
        let (mut px, mut torso) = (Vec::new(), Vec::new());
        for j in BODY {
            let (p, errors) = joint(&seen, mirrored, j, reject)?;
            joints[j] = p;
            px.extend(errors.iter().map(|e| e.0));
            torso.extend(errors.iter().map(|e| e.1));
        }
        Some(Frame3d {
            joints,
            residual_px: median(px),
            residual_torso: median(torso),
            mirrored,
        })
    };
    let best = (0..1u32 << seen.len())
        .step_by(2)
        .filter_map(|m| labelling(m, false))
        .min_by(|a, b| a.residual_torso.total_cmp(&b.residual_torso))?;
    let mut frame = labelling(best.mirrored, true)?;
    if !faces_its_nose(&frame.joints) {
        let joints = frame.joints.clone();
        for j in BODY {
            frame.joints[j] = joints[mirror(j)];
        }
        frame.mirrored ^= (1 << seen.len()) - 1;
    }
    Some(frame)
}

/// Whether the labels put the body's left on its left: forward (left × up, from the shoulder
/// and hip lines and the spine) points the way the nose stands out of the shoulders.
pub fn faces_its_nose(joints: &[DVec3]) -> bool {
    let mid = |a: usize, b: usize| (joints[a] + joints[b]) * 0.5;
    let shoulders = mid(idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER);
    let left = joints[idx::LEFT_SHOULDER] - joints[idx::RIGHT_SHOULDER] + joints[idx::LEFT_HIP]
        - joints[idx::RIGHT_HIP];
    let up = shoulders - mid(idx::LEFT_HIP, idx::RIGHT_HIP);
    left.cross(up).dot(joints[idx::NOSE] - shoulders) > 0.0
}

/// The reference over the frames `0..frames` of the timeline the offsets are counted on.
pub fn build(views: &[View], frames: i64) -> Vec<Option<Frame3d>> {
    (0..frames)
        .map(|f| frame(views, f).filter(|r| r.residual_torso <= ACCEPT))
        .collect()
}

/// The median reprojection error (of the torso) over the frames every view sees, and how
/// many frames that is.
fn sync_score(views: &[View], frames: i64) -> (f64, usize) {
    let all: Vec<f64> = (0..frames)
        .filter(|&f| views.iter().all(|v| seen(v, f).is_some()))
        .filter_map(|f| frame(views, f))
        .map(|r| r.residual_torso)
        .collect();
    let n = all.len();
    (median(all), n)
}

/// Each view's offset after the first (which stays), in frames within [`MAX_SHIFT_SECS`] at
/// `fps`: the one whose triangulation reprojects best over the frames all views see (at least
/// half of `frames`), one camera at a time, twice round.
pub fn synchronise(views: &mut [View], frames: i64, fps: f64) {
    let reach = (MAX_SHIFT_SECS * fps).round() as i64;
    for _ in 0..2 {
        for k in 1..views.len() {
            let mut best = (f64::INFINITY, views[k].offset);
            for shift in -reach..=reach {
                views[k].offset = shift;
                let (score, n) = sync_score(views, frames);
                if 2 * n as i64 >= frames && score < best.0 {
                    best = (score, shift);
                }
            }
            views[k].offset = best.1;
        }
    }
}

/// The limbs' landmarks (shoulders, elbows, wrists, hips, knees, ankles).
pub const LIMBS: [usize; 12] = [11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28];

/// Whether image points label left and right as a reference's projection does: the limbs
/// nearer the projection's same-side points than the other side's.
pub fn labels_agree(image: &Points, projected: &[DVec2]) -> bool {
    let at = |i: usize| DVec2::new(image[i][0].into(), image[i][1].into());
    let (mut same, mut swapped) = (0.0, 0.0);
    for &j in &LIMBS {
        same += at(j).distance(projected[j]);
        swapped += at(j).distance(projected[mirror(j)]);
    }
    same < swapped
}

/// The calibration (`*.qca.txt`) in `dir` and its cameras that have a video named after them
/// there (at least three), or `None`.
pub fn calibrated_cameras(dir: &Path) -> Option<Vec<(Camera, PathBuf)>> {
    let calib = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| Some(e.ok()?.path()))
        .find(|p| p.to_string_lossy().ends_with(".qca.txt"))?;
    let cameras = read_qca(&std::fs::read_to_string(&calib).unwrap())
        .unwrap_or_else(|e| panic!("{}: {e}", calib.display()));
    let found: Vec<_> = cameras
        .into_iter()
        .filter_map(|c| {
            let video = dir.join(format!("{}.mp4", c.name));
            video.is_file().then_some((c, video))
        })
        .collect();
    (found.len() >= 3).then_some(found)
}

/// Calibrated cameras with MediaPipe's run over every frame of each, synchronised.
pub struct Rig {
    pub cameras: Vec<(Camera, PathBuf)>,
    pub runs: Vec<MediaPipeRun>,
    /// Per camera: its frame `f + offset` is the timeline's frame `f`.
    pub offsets: Vec<i64>,
    pub fps: f64,
    /// The timeline's length.
    pub frames: i64,
}

impl Rig {
    /// MediaPipe (`python`) over every calibrated camera of `dir`, synchronised; `None` when
    /// `dir` holds no calibration with three cameras' videos.
    pub fn new(python: &Path, dir: &Path) -> Option<Rig> {
        let cameras = calibrated_cameras(dir)?;
        let runs: Vec<MediaPipeRun> = cameras
            .iter()
            .map(|(_, v)| run_mediapipe(python, v, None))
            .collect();
        let fps = FfmpegSource::open(&cameras[0].1).ok()?.fps()?;
        let frames = runs.iter().map(|r| r.frames.len()).max()? as i64;
        let mut rig = Rig {
            offsets: vec![0; cameras.len()],
            cameras,
            runs,
            fps,
            frames,
        };
        let mut views: Vec<View> = (0..rig.cameras.len()).map(|k| rig.view(k)).collect();
        synchronise(&mut views, frames, fps);
        let offsets = views.iter().map(|v| v.offset).collect();
        rig.offsets = offsets;
        Some(rig)
    }

    /// Camera `k`'s view.
    pub fn view(&self, k: usize) -> View<'_> {
        let run = &self.runs[k];
        View {
            cam: &self.cameras[k].0,
            video: DVec2::new(run.width.into(), run.height.into()),
            frames: &run.frames,
            offset: self.offsets[k],
        }
    }

    /// The reference from every camera but `left_out` (`None`: from all).
    pub fn reference(&self, left_out: Option<usize>) -> Vec<Option<Frame3d>> {
        let views: Vec<View> = (0..self.cameras.len())
            .filter(|&k| Some(k) != left_out)
            .map(|k| self.view(k))
            .collect();
        build(&views, self.frames)
    }

    /// The camera whose video is `path`.
    pub fn camera_of(&self, path: &Path) -> Option<usize> {
        self.cameras.iter().position(|(_, v)| v == path)
    }
}
