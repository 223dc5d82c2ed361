//! A locomotion clip looping in step, for live grafts: one stride (a foot's landing to its
//! next landing, the stride whose end pose best matches its start), closed so its last frame
//! is its first, played on a continuous clock. Each time the stride wraps, the walker carries
//! on from where the stride ended (its travel and turn accumulate) instead of jumping back,
//! so the phase and the root's path are continuous; the stride's plant flags come with every
//! sample for the foot lock (none for an in-place clip: `footplant::treadmill`).
//!
//! Closing the loop: the difference between the stride's end and start pose (each bone's
//! local rotation, the root's height) is spread linearly over the stride, so the seam has no
//! step; the root's travel and turn over the stride are kept as the per-stride motion.

use glam::{Quat, Vec3};

use super::warp::plant_events;
use super::GraftError;
use crate::clip::Clip;
use crate::footplant::{PlantTrack, MAX_FEET};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// A stride looping on a continuous clock. [`GaitLoop::advance`] allocates nothing.
#[derive(Debug, Clone)]
pub struct GaitLoop {
    skeleton: Skeleton,
    /// The stride's frames, closed (the last equals the first, moved by one stride).
    poses: Vec<Pose>,
    /// Plant flags per stride frame (frame-major, `num_legs` per frame).
    plants: Vec<bool>,
    num_legs: usize,
    frame_secs: f64,
    /// The bone carrying the walk (its translation changes), and up in its parent's frame.
    mover: BoneId,
    up: Vec3,
    /// Per stride: turn about up and travel (in the mover's parent frame, horizontal).
    stride_turn: f32,
    stride_travel: Vec3,
    /// Where the current stride starts from: accumulated turn and offset.
    turn: f32,
    offset: Vec3,
    phase_secs: f64,
    flags: [bool; MAX_FEET],
}

/// The angle of `q`'s twist about `axis` (unit).
fn twist_angle(q: Quat, axis: Vec3) -> f32 {
    let v = Vec3::new(q.x, q.y, q.z).dot(axis);
    2.0 * v.atan2(q.w)
}

fn flat(v: Vec3, up: Vec3) -> Vec3 {
    v - up * v.dot(up)
}

impl GaitLoop {
    /// The loop of `clip` with its plant track (`plants`, from detection on the clip; its leg
    /// order is the flags' order), `up` the clip skeleton's up.
    pub fn new(clip: &Clip, plants: &PlantTrack, up: Vec3) -> Result<GaitLoop, GraftError> {
        let skel = &clip.skeleton;
        let mover = mover(clip);
        // The mover's parent stands still: its frame at the first pose is the frame for all.
        let parent_rot = skel
            .parent(mover)
            .map(|p| crate::fk::world_transforms(skel, &clip.poses[0])[p.index()].rotation)
            .unwrap_or(Quat::IDENTITY);
        let up = (parent_rot.inverse() * up)
            .try_normalize()
            .unwrap_or(Vec3::Y);
        let m = mover.index();
        let (a, b) = best_stride(clip, plants, m, up)?;
        let (start, end) = (&clip.poses[a], &clip.poses[b]);
        let stride_turn = twist_angle(end.rotations[m] * start.rotations[m].inverse(), up);
        let yaw = Quat::from_axis_angle(up, stride_turn);
        let stride_travel = flat(end.translations[m], up) - yaw * flat(start.translations[m], up);
        let poses = close(&clip.poses[a..=b], m, up, yaw);
        let num_legs = plants.legs.len().min(MAX_FEET);
        // An in-place clip's standing feet slide with its belt under a body that never
        // travels: nothing for the lock to pin, so its flags stay down.
        let in_place = plants.belt().is_some();
        let plants = (a..=b)
            .flat_map(|f| (0..num_legs).map(move |l| (f, l)))
            .map(|(f, l)| plants.is_planted(f, l) && !in_place)
            .collect();
        Ok(GaitLoop {
            skeleton: (**skel).clone(),
            poses,
            plants,
            num_legs,
            frame_secs: clip.frame_time_secs,
            mover,
            up,
            stride_turn,
            stride_travel,
            turn: 0.0,
            offset: Vec3::ZERO,
            phase_secs: 0.0,
            flags: [false; MAX_FEET],
        })
    }

    /// One stride's duration, seconds.
    pub fn stride_secs(&self) -> f64 {
        (self.poses.len() - 1) as f64 * self.frame_secs
    }

    /// Seconds into the current stride.
    pub fn phase_secs(&self) -> f64 {
        self.phase_secs
    }

    /// The clip's skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// Moves the clock on by `dt_secs` and writes the pose there into `out` (a pose of the
    /// clip's skeleton); returns the plant flags per leg. Allocates nothing.
    pub fn advance(&mut self, dt_secs: f64, out: &mut Pose) -> &[bool] {
        let stride = self.stride_secs();
        self.phase_secs += dt_secs.max(0.0);
        while stride > 0.0 && self.phase_secs >= stride {
            self.phase_secs -= stride;
            // The next stride starts where this one ended.
            let yaw = Quat::from_axis_angle(self.up, self.turn);
            self.offset += yaw * self.stride_travel;
            self.turn += self.stride_turn;
        }
        self.sample(out)
    }

    fn sample(&mut self, out: &mut Pose) -> &[bool] {
        if out.check(&self.skeleton).is_err() {
            return &self.flags[..0];
        }
        let f = self.phase_secs / self.frame_secs;
        let i = (f.floor() as usize).min(self.poses.len() - 1);
        let j = (i + 1).min(self.poses.len() - 1);
        out.interpolate_into(&self.poses[i], &self.poses[j], (f - i as f64) as f32);
        let m = self.mover.index();
        let yaw = Quat::from_axis_angle(self.up, self.turn);
        let t = out.translations[m];
        let height = self.up * t.dot(self.up);
        out.translations[m] = yaw * flat(t, self.up) + self.offset + height;
        out.rotations[m] = (yaw * out.rotations[m]).normalize();
        let near = if f - i as f64 > 0.5 { j } else { i };
        for (l, flag) in self.flags.iter_mut().take(self.num_legs).enumerate() {
            *flag = self.plants[near * self.num_legs + l];
        }
        &self.flags[..self.num_legs]
    }
}

/// The shallowest bone whose translation changes over the clip (the hips of a BVH, under a
/// glTF's static armature nodes); the first bone when none does.
fn mover(clip: &Clip) -> BoneId {
    let first = &clip.poses[0];
    let moves = |b: usize| {
        clip.poses
            .iter()
            .any(|p| (p.translations[b] - first.translations[b]).length() > 1e-4)
    };
    (0..clip.skeleton.num_bones())
        .find(|&b| moves(b))
        .map(|b| BoneId(b as u16))
        .unwrap_or(BoneId(0))
}

/// The stride to loop: among strides (consecutive landings of one foot, another foot landing
/// between) that travel at least half as far as the farthest one (a clip's idle shuffles
/// start and end alike but do not walk), the one whose end pose is nearest its start, by the
/// summed rotation angles of every bone below the mover.
fn best_stride(
    clip: &Clip,
    plants: &PlantTrack,
    mover: usize,
    up: Vec3,
) -> Result<(usize, usize), GraftError> {
    let events = plant_events(plants);
    let distance = |a: &Pose, b: &Pose| -> f32 {
        let pairs = a.rotations.iter().zip(&b.rotations).skip(mover + 1);
        pairs.map(|(x, y)| crate::approx::quat_angle(*x, *y)).sum()
    };
    let travel = |a: usize, b: usize| {
        let d = clip.poses[b].translations[mover] - clip.poses[a].translations[mover];
        flat(d, up).length()
    };
    let strides: Vec<(usize, usize)> = events
        .iter()
        .enumerate()
        .filter_map(|(k, e)| {
            let next = events[k + 1..].iter().position(|n| n.foot == e.foot)?;
            (next > 0).then(|| (e.frame, events[k + 1 + next].frame))
        })
        .collect();
    let farthest = strides
        .iter()
        .map(|&(a, b)| travel(a, b))
        .fold(0.0f32, f32::max);
    strides
        .into_iter()
        .filter(|&(a, b)| travel(a, b) >= 0.5 * farthest)
        .map(|(a, b)| (distance(&clip.poses[a], &clip.poses[b]), (a, b)))
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(_, s)| s)
        .ok_or(GraftError::NoStride)
}

/// The stride with its end pose brought onto its start (turned by the stride's turn at the
/// root), the difference spread linearly over the frames.
fn close(frames: &[Pose], mover: usize, up: Vec3, yaw: Quat) -> Vec<Pose> {
    let (start, end) = (&frames[0], &frames[frames.len() - 1]);
    let wanted = |b: usize| {
        if b == mover {
            yaw * start.rotations[b]
        } else {
            start.rotations[b]
        }
    };
    let fixes: Vec<Quat> = (0..start.rotations.len())
        .map(|b| {
            let d = wanted(b) * end.rotations[b].inverse();
            if d.w < 0.0 {
                -d
            } else {
                d
            }
        })
        .collect();
    let rise = (start.translations[mover] - end.translations[mover]).dot(up);
    let last = (frames.len() - 1).max(1) as f32;
    frames
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let t = k as f32 / last;
            let mut q = p.clone();
            for (r, fix) in q.rotations.iter_mut().zip(&fixes) {
                *r = (Quat::IDENTITY.slerp(*fix, t) * *r).normalize();
            }
            q.translations[mover] += up * (rise * t);
            q
        })
        .collect()
}
