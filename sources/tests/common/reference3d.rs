//! A 3D reference of one person from several calibrated views' 2D landmarks (another program's:
//! the tests give it MediaPipe's), robust to what such landmarks get wrong:
//! - a view that reads the person mirrored (left and right swapped, whole or in part of the
//!   clip): every labelling of the views is tried and the one whose triangulation reprojects
//!   best, its left and right limbs alike long, is kept, per frame (the reprojection alone
//!   can prefer a wrong labelling of a view that sees the body from the side: on the desk
//!   set, with three views, one such pulled the shoulders 0.62 m apart and one forearm to
//!   0.13 m against the other's 0.77);
//! - a wrong joint in one view: with three views or more, a view whose reprojection of a joint
//!   misses by more than [`REJECT`] of the person's torso there is left out for that joint;
//!   when that leaves two views, which of the three was wrong is not known (two views agree
//!   on nearly any point along their epipolar lines), so the joint is not held in that frame
//!   ([`Frame3d::held`]; the desk set's right elbow behind the board, its three views
//!   50-120 px apart, came out of two of them 0.6 m from the shoulder);
//! - which side is the body's left then comes from the body, not from any view's labels: the
//!   face (nose) is in front, and the body's left is on its left (left × up = forward; up
//!   along the spine, or the cameras' up for a body seen without its hips);
//! - a rig that sees only part of the body (the desk set's seated man: hips and legs below
//!   the pictures): the reference holds the [`BODY`] landmarks MediaPipe sees in most frames
//!   of three views or more ([`Body::seen`]);
//! - cameras that did not start together: each camera's frame offset is the one where every
//!   camera's own 2D best agrees with the other cameras' triangulation, over every frame
//!   (searched within [`MAX_SHIFT_SECS`]).
//!
//! Two calibration formats are found by listing: a Qualisys export beside videos named after
//! its cameras (pose2sim), and caliscope's `camera_array.toml` ([`caliscope_sets`]). Each
//! view's landmarks count by their visibility. Needs `common/mediapipe.rs` and
//! `common/multiview.rs` included beside it as `mediapipe` and `multiview`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{FfmpegSource, FrameSource};

use crate::mediapipe::{run_mediapipe, MediaPipeRun, Points};
use crate::multiview::{read_caliscope, read_qca, triangulate, Camera};

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

/// What a reference holds: its landmarks (of [`BODY`]) and the world's up as the cameras see
/// it (which tells left from right when the hips are not held).
#[derive(Clone, Debug)]
pub struct Body {
    pub joints: Vec<usize>,
    pub up: DVec3,
}

/// A landmark counts as seen in a view's frame at this visibility or more, inside the picture.
pub const SEEN: f32 = 0.5;

impl Body {
    /// Every landmark of [`BODY`].
    pub fn whole() -> Body {
        Body {
            joints: BODY.to_vec(),
            up: DVec3::Z,
        }
    }

    /// The landmarks of [`BODY`] seen in at least half the frames of three views or more
    /// (the nose and shoulders always: left and right are told from them), and the cameras'
    /// mean up.
    pub fn seen(views: &[View]) -> Body {
        let seen_in = |v: &View, j: usize| {
            let frames: Vec<&Points> = v.frames.iter().flatten().collect();
            let inside = frames
                .iter()
                .filter(|p| {
                    let [x, y, vis] = p[j];
                    vis >= SEEN
                        && (0.0..v.video.x as f32).contains(&x)
                        && (0.0..v.video.y as f32).contains(&y)
                })
                .count();
            2 * inside >= frames.len().max(1)
        };
        let joints = BODY
            .into_iter()
            .filter(|&j| {
                [idx::NOSE, idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER].contains(&j)
                    || views.iter().filter(|v| seen_in(v, j)).count() >= 3.min(views.len())
            })
            .collect();
        let up = views
            .iter()
            .map(|v| v.cam.up())
            .sum::<DVec3>()
            .normalize_or_zero();
        Body { joints, up }
    }

    pub fn holds(&self, j: usize) -> bool {
        self.joints.contains(&j)
    }

    /// The point the body's jitter is measured around: the hips' midpoint when held, else
    /// the shoulders'.
    pub fn centre(&self) -> (usize, usize) {
        if self.holds(idx::LEFT_HIP) && self.holds(idx::RIGHT_HIP) {
            (idx::LEFT_HIP, idx::RIGHT_HIP)
        } else {
            (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER)
        }
    }
}

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
    /// Landmarks held (bit per landmark): not those left to two views by a third's dissent.
    pub held: u64,
}

impl Frame3d {
    pub fn holds(&self, j: usize) -> bool {
        self.held >> j & 1 == 1
    }
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
/// Joint `j`: its point, each kept view's (error px, error / torso), and whether it holds.
type Joint = (DVec3, Vec<(f64, f64)>, bool);

fn joint(seen: &[Seen], mirrored: u32, j: usize, reject: bool) -> Option<Joint> {
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
        return Some((p, e, kept.len() >= 3 || kept.len() == seen.len()));
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::INFINITY;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The reference of the whole [`BODY`] at frame `f` from the views that see it (at least
/// two), or `None`.
pub fn frame(views: &[View], f: i64) -> Option<Frame3d> {
    frame_of(views, f, &Body::whole())
}

/// [`frame`] of `body`'s landmarks.
pub fn frame_of(views: &[View], f: i64, body: &Body) -> Option<Frame3d> {
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
        let (mut px, mut torso, mut held) = (Vec::new(), Vec::new(), 0u64);
        for &j in &body.joints {
            let (p, errors, holds) = joint(&seen, mirrored, j, reject)?;
            joints[j] = p;
            held |= u64::from(holds) << j;
            px.extend(errors.iter().map(|e| e.0));
            torso.extend(errors.iter().map(|e| e.1));
        }
        Some(Frame3d {
            joints,
            residual_px: median(px),
            residual_torso: median(torso),
            mirrored,
            held,
        })
    };
    let cost = |r: &Frame3d| r.residual_torso * (1.0 + asymmetry(&r.joints, body));
    let best = (0..1u32 << seen.len())
        .step_by(2)
        .filter_map(|m| labelling(m, false))
        .min_by(|a, b| cost(a).total_cmp(&cost(b)))?;
    let mut frame = labelling(best.mirrored, true)?;
    if !faces_its_nose(&frame.joints, body) {
        let (joints, held) = (frame.joints.clone(), frame.held);
        frame.held = 0;
        for &j in &body.joints {
            frame.joints[j] = joints[mirror(j)];
            frame.held |= (held >> mirror(j) & 1) << j;
        }
        frame.mirrored ^= (1 << seen.len()) - 1;
    }
    Some(frame)
}

/// How unlike the body's left and right limbs are: the mean |ln(left / right)| of the
/// lengths of its upper arms, forearms, thighs and shins that `body` holds (0 for a
/// symmetric body).
pub fn asymmetry(joints: &[DVec3], body: &Body) -> f64 {
    let pairs = [(11, 13), (13, 15), (23, 25), (25, 27)];
    let ratios: Vec<f64> = pairs
        .iter()
        .filter(|&&(a, b)| body.holds(a) && body.holds(b))
        .map(|&(a, b)| {
            let left = joints[a].distance(joints[b]);
            let right = joints[mirror(a)].distance(joints[mirror(b)]);
            (left.max(1e-6) / right.max(1e-6)).ln().abs()
        })
        .collect();
    ratios.iter().sum::<f64>() / ratios.len().max(1) as f64
}

/// Whether the labels put the body's left on its left: forward (left × up, from the shoulder
/// and hip lines and the spine; without the hips, the shoulder line and the cameras' up)
/// points the way the nose stands out of the shoulders.
pub fn faces_its_nose(joints: &[DVec3], body: &Body) -> bool {
    let mid = |a: usize, b: usize| (joints[a] + joints[b]) * 0.5;
    let shoulders = mid(idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER);
    let mut left = joints[idx::LEFT_SHOULDER] - joints[idx::RIGHT_SHOULDER];
    let up = if body.centre() == (idx::LEFT_HIP, idx::RIGHT_HIP) {
        left += joints[idx::LEFT_HIP] - joints[idx::RIGHT_HIP];
        shoulders - mid(idx::LEFT_HIP, idx::RIGHT_HIP)
    } else {
        body.up
    };
    left.cross(up).dot(joints[idx::NOSE] - shoulders) > 0.0
}

/// The reference of `body` over the frames `0..frames` of the timeline the offsets are
/// counted on.
pub fn build(views: &[View], frames: i64, body: &Body) -> Vec<Option<Frame3d>> {
    (0..frames)
        .map(|f| frame_of(views, f, body).filter(|r| r.residual_torso <= ACCEPT))
        .collect()
}

/// How far each view's own 2D lies from the triangulation of the *other* views: the mean,
/// over the views, of the view's mean error (of its torso) on `body`'s held joints, over the
/// frames every view sees of `first..last`; and how many frames that is. Every frame counts
/// (a median keeps the still ones, which fit any offset), and the view scored is not in the
/// triangulation (a late view in it is left out of the joints it misses, which hides it).
fn sync_score(views: &[View], first: i64, last: i64, body: &Body) -> (f64, usize) {
    let frames: Vec<i64> = (first..last)
        .filter(|&f| views.iter().all(|v| seen(v, f).is_some()))
        .collect();
    let per_view: Vec<f64> = (0..views.len())
        .map(|k| {
            let others: Vec<View> = views
                .iter()
                .enumerate()
                .filter(|&(o, _)| o != k)
                .map(|(_, v)| View { ..*v })
                .collect();
            let errors: Vec<f64> = frames
                .iter()
                .filter_map(|&f| Some((frame_of(&others, f, body)?, own_points(&views[k], f)?)))
                .flat_map(|(r, p)| view_errors(&r, &views[k], p, body))
                .collect();
            errors.iter().sum::<f64>() / errors.len().max(1) as f64
        })
        .collect();
    let score = per_view.iter().sum::<f64>() / per_view.len().max(1) as f64;
    (score, frames.len())
}

fn own_points<'a>(view: &View<'a>, f: i64) -> Option<&'a Points> {
    view.frames
        .get(usize::try_from(f + view.offset).ok()?)?
        .as_ref()
}

/// A view's 2D joints' distances (of its torso) from the reference's projection, its labels
/// read the way round (as they are, or mirrored) that fits the projection better.
fn view_errors(r: &Frame3d, view: &View, p: &Points, body: &Body) -> Vec<f64> {
    let at = |i: usize| DVec2::new(p[i][0].into(), p[i][1].into());
    let torso = ((at(idx::LEFT_SHOULDER) + at(idx::RIGHT_SHOULDER))
        - (at(idx::LEFT_HIP) + at(idx::RIGHT_HIP)))
    .length()
        * 0.5;
    let cost = |m: fn(usize) -> usize| -> Vec<f64> {
        body.joints
            .iter()
            .filter(|&&j| r.holds(j) && r.holds(m(j)))
            .map(|&j| {
                let projected = view.cam.project(view.video, r.joints[m(j)]);
                projected.map_or(1e3, |q| at(j).distance(q) / torso.max(1.0))
            })
            .collect()
    };
    let (same, swapped) = (cost(|j| j), cost(mirror));
    let total = |v: &[f64]| v.iter().sum::<f64>();
    if total(&same) <= total(&swapped) {
        same
    } else {
        swapped
    }
}

/// Each view's offset after the first (which stays), in frames within [`MAX_SHIFT_SECS`] at
/// `fps`: the one where the views' own 2D best agree with the other views' triangulation
/// ([`sync_score`], over the frames every view sees, the search's reach off both ends, at
/// least half of `frames`), one camera at a time, twice round.
pub fn synchronise(views: &mut [View], frames: i64, fps: f64, body: &Body) {
    let reach = (MAX_SHIFT_SECS * fps).round() as i64;
    for _ in 0..2 {
        for k in 1..views.len() {
            let mut best = (f64::INFINITY, views[k].offset);
            for shift in -reach..=reach {
                views[k].offset = shift;
                let (score, n) = sync_score(views, reach, frames - reach, body);
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

/// Whether image points label left and right as a reference's projection does: `body`'s
/// limbs nearer the projection's same-side points than the other side's.
pub fn labels_agree(image: &Points, projected: &[DVec2], body: &Body) -> bool {
    let at = |i: usize| DVec2::new(image[i][0].into(), image[i][1].into());
    let (mut same, mut swapped) = (0.0, 0.0);
    for &j in LIMBS.iter().filter(|&&j| body.holds(j)) {
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

/// Whether `stem` names camera `id` as a word: `cam<ID>` or `cam_<ID>`, no digit after.
fn names_camera(stem: &str, id: &str) -> bool {
    let stem = stem.to_ascii_lowercase();
    ["cam", "cam_"].iter().any(|prefix| {
        let key = format!("{prefix}{id}");
        stem.match_indices(&key).any(|(at, _)| {
            let before = stem[..at].chars().next_back();
            let after = stem[at + key.len()..].chars().next();
            !before.is_some_and(|c| c.is_ascii_alphanumeric())
                && !after.is_some_and(|c| c.is_ascii_digit())
        })
    })
}

fn is_video(path: &Path) -> bool {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    ["mp4", "avi", "mkv", "mov", "webm"]
        .iter()
        .any(|e| ext.eq_ignore_ascii_case(e))
}

/// A calibrated set of cameras found in the shared data.
pub struct CalibratedSet {
    /// Its folder's name.
    pub name: String,
    pub cameras: Vec<(Camera, PathBuf)>,
    /// Each camera's frame offset from the set's own frame times, when it has them.
    pub offsets: Option<Vec<i64>>,
}

/// Each camera's offset (its video's frame `f + offset` is the set's frame `f`) from a
/// caliscope `timestamps.csv` (`sync_index,cam_id,frame_index,frame_time`: a camera's rows
/// in sync order are its video's frames in order), `None` when a camera has no rows or its
/// frames do not follow the sync index one for one (a dropped frame: left to the search).
pub fn caliscope_offsets(text: &str, cameras: &[(Camera, PathBuf)]) -> Option<Vec<i64>> {
    let mut rows: Vec<(i64, String)> = Vec::new();
    for line in text.lines().skip(1) {
        let mut fields = line.split(',');
        let sync = fields.next()?.trim().parse().ok()?;
        rows.push((sync, format!("cam_{}", fields.next()?.trim())));
    }
    let first = rows.iter().map(|r| r.0).min()?;
    cameras
        .iter()
        .map(|(cam, _)| {
            let mut syncs: Vec<i64> = rows
                .iter()
                .filter(|r| r.1 == cam.name)
                .map(|r| r.0 - first)
                .collect();
            syncs.sort_unstable();
            let offset = -*syncs.first()?;
            syncs
                .iter()
                .enumerate()
                .all(|(rank, &s)| rank as i64 == s + offset)
                .then_some(offset)
        })
        .collect()
}

/// Every caliscope calibration (`camera_array.toml`) under `root` (up to three folders
/// down), with its cameras that have a video, when at least three do, and their offsets
/// from the `timestamps.csv` beside it. A camera's video is found by listing the calibration's folder
/// and the folders above it up to `root`: beside the calibration, a video naming the camera
/// (`cam<ID>` or `cam_<ID>`); further up, one that also holds every word of the
/// calibration folder's name (`caliscope_desk` → `…desk…cam2…caliscope…`). A camera with
/// no such video, or more than one, is left out (and said).
pub fn caliscope_sets(root: &Path) -> Vec<CalibratedSet> {
    let calibrations: Vec<PathBuf> = crate::shared_data::files_under(root)
        .into_iter()
        .filter(|path| path.file_name().is_some_and(|n| n == "camera_array.toml"))
        .collect();
    let mut sets = Vec::new();
    for calib in calibrations {
        let dir = calib.parent().unwrap_or(root);
        let name = dir
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let words: Vec<String> = name
            .to_ascii_lowercase()
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| !w.is_empty())
            .map(str::to_string)
            .collect();
        let cameras = read_caliscope(&std::fs::read_to_string(&calib).unwrap())
            .unwrap_or_else(|e| panic!("{}: {e}", calib.display()));
        let mut candidates: Vec<(PathBuf, bool)> = Vec::new();
        for folder in dir.ancestors().take_while(|d| d.starts_with(root)) {
            let mut here: Vec<PathBuf> = std::fs::read_dir(folder)
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.path())
                .filter(|p| is_video(p))
                .collect();
            here.sort();
            candidates.extend(here.into_iter().map(|p| (p, folder == dir)));
        }
        let found: Vec<(Camera, PathBuf)> = cameras
            .into_iter()
            .filter_map(|cam| {
                let id = cam.name.trim_start_matches("cam_").to_string();
                let of: Vec<&PathBuf> = candidates
                    .iter()
                    .filter(|(p, beside)| {
                        let stem = p.file_stem().unwrap_or_default().to_string_lossy();
                        let lower = stem.to_ascii_lowercase();
                        names_camera(&stem, &id)
                            && (*beside || words.iter().all(|w| lower.contains(w.as_str())))
                    })
                    .map(|(p, _)| p)
                    .collect();
                match of[..] {
                    [video] => Some((cam, video.clone())),
                    _ => {
                        println!(
                            "{name}: {} has {} videos ({of:?}); left out",
                            cam.name,
                            of.len()
                        );
                        None
                    }
                }
            })
            .collect();
        if found.len() >= 3 {
            let offsets = std::fs::read_to_string(dir.join("timestamps.csv"))
                .ok()
                .and_then(|t| caliscope_offsets(&t, &found));
            sets.push(CalibratedSet {
                name,
                cameras: found,
                offsets,
            });
        } else {
            println!(
                "{name}: {} cameras with a video, fewer than three; left out",
                found.len()
            );
        }
    }
    sets
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
    /// What the reference holds.
    pub body: Body,
}

impl Rig {
    /// MediaPipe (`python`) over every calibrated camera of `dir`, synchronised; `None` when
    /// `dir` holds no calibration with three cameras' videos.
    pub fn new(python: &Path, dir: &Path) -> Option<Rig> {
        Some(Rig::of(python, calibrated_cameras(dir)?, None))
    }

    /// MediaPipe (`python`) over every camera of `cameras`, at `offsets` when known, else
    /// synchronised.
    pub fn of(python: &Path, cameras: Vec<(Camera, PathBuf)>, offsets: Option<Vec<i64>>) -> Rig {
        let runs: Vec<MediaPipeRun> = cameras
            .iter()
            .map(|(_, v)| run_mediapipe(python, v, None))
            .collect();
        let fps = FfmpegSource::open(&cameras[0].1).unwrap().fps().unwrap();
        let frames = runs.iter().map(|r| r.frames.len()).max().unwrap_or(0) as i64;
        let mut rig = Rig {
            offsets: vec![0; cameras.len()],
            cameras,
            runs,
            fps,
            frames,
            body: Body::whole(),
        };
        let mut views: Vec<View> = (0..rig.cameras.len()).map(|k| rig.view(k)).collect();
        let body = Body::seen(&views);
        rig.offsets = match offsets {
            Some(known) => known,
            None => {
                synchronise(&mut views, frames, fps, &body);
                views.iter().map(|v| v.offset).collect()
            }
        };
        rig.body = body;
        rig
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
        build(&views, self.frames, &self.body)
    }

    /// The camera whose video is `path`.
    pub fn camera_of(&self, path: &Path) -> Option<usize> {
        self.cameras.iter().position(|(_, v)| v == path)
    }
}
