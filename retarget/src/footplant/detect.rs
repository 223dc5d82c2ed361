//! Footplant detection: a foot is planted while its heel (foot joint) or ball (toes joint) is
//! near the ground AND barely moving (seed 002). Thresholds scale with the leg's length, and
//! "barely moving" with the pace too: slow is under a share of the body's speed over the
//! ground (over about a step) when that is more (a run's standing foot seems to move faster
//! than a walk's; a swinging foot always overtakes the body). Speeds are measured over at
//! least `window_secs` (raw mocap feet jitter at 120 Hz, so frame-to-frame differences would
//! read a standing foot as moving). Hysteresis (looser thresholds to stay planted than to
//! plant) and a shortest plant keep the state from flickering.
//!
//! The ground is read from the motion, never assumed at 0: each contact joint's ground is the
//! lowest level it reaches while slow (where it stands), so a rig whose ball joint sits 3 cm
//! above its sole, or a capture whose floor is at y = −1, needs no calibration.
//!
//! Two modes share the rules:
//! - [`PlantDetector`] (live, causal): speed from the sample `window_secs` back, so a plant is
//!   seen about half a window late (8 ms for the default 1/30 s); the ground is the lowest slow
//!   level seen so far. No allocation per sample.
//! - [`detect_clip`] (files, two-sided): centred speeds, the ground from the whole clip (a low
//!   percentile of slow frames, robust to a glitch), then plants shorter than `min_plant_secs`
//!   dropped and gaps shorter than `min_gap_secs` closed.

use glam::Vec3;

use super::rig::{Leg, MAX_FEET};
use super::treadmill::{belt_velocity, stance_band, Contacts};
use crate::fk::{forward_kinematics, WorldTransform};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// Heel and ball.
const JOINTS_PER_FOOT: usize = 2;
/// Samples the causal detector keeps (enough for a 1/30 s window up to 900 Hz input).
const RING: usize = 32;
/// Positions kept per sample: every contact joint, then the body (the legs' hips' midpoint).
const TRACKED: usize = JOINTS_PER_FOOT * MAX_FEET + 1;
const BODY: usize = TRACKED - 1;
/// The body's pace is its speed over the ground over about this long (a step of a walk): the
/// hips speed up and slow down within every step, the pace does not.
const PACE_SECS: f32 = 0.5;

/// Thresholds of the detector, relative to each leg's length (hip to ankle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantSettings {
    /// A contact joint is near the ground below this fraction of the leg length above its
    /// ground (0.05: 4 cm on a 0.8 m leg).
    pub height_ratio: f32,
    /// ... and slow below this many leg lengths per second (0.25: 20 cm/s on a 0.8 m leg; a
    /// swinging foot moves at 2–5 m/s, a standing one jitters at 2–15 cm/s over 1/30 s, a
    /// ball pivoting under a rising heel at 10–25 cm/s) ...
    pub speed_ratio: f32,
    /// ... or below this fraction of the body's pace (the hips' speed over the ground over
    /// about a step), whichever is more. A standing foot carries the body forward while a
    /// swinging one overtakes it (about twice its speed on average), at any pace; what a
    /// standing foot seems to move over the speed window grows with the pace (a window
    /// straddling a landing or a toe-off takes in some of the swing, a foot rolling over its
    /// ball turns faster), so a run's stance reads 0.3–0.9 leg lengths a second where a
    /// walk's reads under 0.25 (0.15: a body running at 3 leg lengths a second allows 0.45;
    /// a walk, under 1.7, keeps `speed_ratio`).
    pub body_speed_ratio: f32,
    /// A planted foot stays planted until its joints exceed the thresholds times this.
    pub release_factor: f32,
    /// Speeds are measured over at least this long.
    pub window_secs: f32,
    /// Plants shorter than this are noise (two-sided mode drops them; the causal mode holds a
    /// plant at least this long).
    pub min_plant_secs: f32,
    /// Two-sided mode closes gaps shorter than this between two plants of one foot.
    pub min_gap_secs: f32,
}

impl Default for PlantSettings {
    fn default() -> Self {
        PlantSettings {
            height_ratio: 0.05,
            speed_ratio: 0.25,
            body_speed_ratio: 0.15,
            release_factor: 1.3,
            window_secs: 1.0 / 30.0,
            min_plant_secs: 1.0 / 30.0,
            min_gap_secs: 1.0 / 30.0,
        }
    }
}

/// The contact joints of a leg: heel, and ball when the rig has one.
fn contacts(leg: &Leg) -> [Option<BoneId>; JOINTS_PER_FOOT] {
    [Some(leg.foot), leg.toes]
}

/// Per-joint evidence of one sample.
#[derive(Debug, Clone, Copy)]
struct Reading {
    height_above_ground: f32,
    speed: f32,
}

/// Which of a foot's contact joints hold (near their ground and slow, the plant rule's own
/// test): what a planted foot may turn about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Contact {
    /// The heel alone: a heel strike, the toes still coming down.
    Heel,
    /// The ball alone: the heel rising at a toe-off, or a turn on the ball.
    Ball,
    /// Both: the foot stands flat.
    Flat,
}

/// The contact of a foot whose heel and ball hold or not (`None`: no such joint).
fn contact_of(heel: Option<bool>, ball: Option<bool>) -> Option<Contact> {
    match (heel, ball) {
        (Some(true), Some(false)) => Some(Contact::Heel),
        (Some(false), Some(true)) => Some(Contact::Ball),
        (Some(true), Some(true)) => Some(Contact::Flat),
        _ => None,
    }
}

/// Whether a contact joint's reading holds: near its ground (below `h`) and slow (below `v`),
/// both scaled by `scale` (the release factor for a planted foot).
fn holds(r: &Reading, h: f32, v: f32, scale: f32) -> bool {
    r.height_above_ground < h * scale && r.speed < v * scale
}

/// The speed below which `leg`'s contact joints count as slow at the body's `pace`.
fn slow_below(settings: &PlantSettings, leg: &Leg, pace: f32) -> f32 {
    (settings.speed_ratio * leg.length).max(settings.body_speed_ratio * pace)
}

/// Where the body is: the midpoint of the legs' hip joints (a pose's world transforms).
fn body_position(legs: &[Leg], worlds: &[WorldTransform]) -> Vec3 {
    let sum: Vec3 = legs
        .iter()
        .map(|l| worlds[l.upper.index()].translation)
        .sum();
    sum / legs.len().max(1) as f32
}

/// The hysteresis rule shared by both modes: plant when some contact joint is near and slow;
/// stay planted while some joint is within the looser release thresholds.
fn next_state(planted: bool, readings: &[Option<Reading>], h: f32, v: f32, k: f32) -> bool {
    let scale = if planted { k } else { 1.0 };
    readings.iter().flatten().any(|r| holds(r, h, v, scale))
}

/// Live, causal footplant detection on one skeleton. Build once, call [`PlantDetector::push`]
/// per source frame; allocates nothing after [`PlantDetector::new`].
#[derive(Debug, Clone)]
pub struct PlantDetector {
    legs: Vec<Leg>,
    up: Vec3,
    settings: PlantSettings,
    worlds: Vec<WorldTransform>,
    /// Ring of (time, contact joint and body positions).
    times: [f64; RING],
    positions: [[Vec3; TRACKED]; RING],
    head: usize,
    len: usize,
    now_secs: f64,
    grounds: [f32; JOINTS_PER_FOOT * MAX_FEET],
    planted: [bool; MAX_FEET],
    planted_since: [f64; MAX_FEET],
    /// The body's pace: its speed over the ground, low-passed over about [`PACE_SECS`] from
    /// the first speed measured (none yet: `None`).
    pace: Option<f32>,
    /// Per leg, the last sample's foot (least of its contacts) and heel above their grounds.
    lifts: [f32; MAX_FEET],
    heel_lifts: [f32; MAX_FEET],
    /// Per leg, its ball's speed over the release speed ([`PlantDetector::ball_speeds`]).
    ball_speeds: [f32; MAX_FEET],
    /// Per leg, which contacts of its foot hold ([`contact_of`]).
    contacts: [Option<Contact>; MAX_FEET],
}

impl PlantDetector {
    /// A detector for `legs` of `skeleton`, with `up` the skeleton's up (unit).
    pub fn new(skeleton: &Skeleton, legs: &[Leg], up: Vec3, settings: PlantSettings) -> Self {
        PlantDetector {
            legs: legs.iter().copied().take(MAX_FEET).collect(),
            up: up.try_normalize().unwrap_or(Vec3::Y),
            settings,
            worlds: vec![WorldTransform::IDENTITY; skeleton.num_bones()],
            times: [0.0; RING],
            positions: [[Vec3::ZERO; TRACKED]; RING],
            head: 0,
            len: 0,
            now_secs: 0.0,
            grounds: [f32::INFINITY; JOINTS_PER_FOOT * MAX_FEET],
            planted: [false; MAX_FEET],
            planted_since: [0.0; MAX_FEET],
            pace: None,
            lifts: [0.0; MAX_FEET],
            heel_lifts: [0.0; MAX_FEET],
            ball_speeds: [0.0; MAX_FEET],
            contacts: [None; MAX_FEET],
        }
    }

    /// The legs, in the order of [`PlantDetector::planted`].
    pub fn legs(&self) -> &[Leg] {
        &self.legs
    }

    /// Forgets the motion seen so far (a source restarted or seeked); keeps the grounds.
    pub fn reset(&mut self) {
        self.len = 0;
        self.planted = [false; MAX_FEET];
        self.pace = None;
    }

    /// Current state per leg.
    pub fn planted(&self) -> &[bool] {
        &self.planted[..self.legs.len()]
    }

    /// Per leg, how high the foot stood above its ground at the last sample: the least of its
    /// contacts' heights (source units; 0 before a ground is known), as [`PlantTrack::lifts`].
    pub fn lifts(&self) -> &[f32] {
        &self.lifts[..self.legs.len()]
    }

    /// The same for the heel (foot joint) alone, as [`PlantTrack::heel_lifts`].
    pub fn heel_lifts(&self) -> &[f32] {
        &self.heel_lifts[..self.legs.len()]
    }

    /// Per leg, how fast its ball (its heel where it has none) moved at the last sample, as a
    /// share of the speed a planted foot is let go at (1: let go, by speed).
    pub fn ball_speeds(&self) -> &[f32] {
        &self.ball_speeds[..self.legs.len()]
    }

    /// Per leg, which contacts of its foot held at the last sample, as
    /// [`PlantTrack::contacts`].
    pub fn contacts(&self) -> &[Option<Contact>] {
        &self.contacts[..self.legs.len()]
    }

    /// Takes the next source pose, `dt_secs` after the previous one, and returns the state per
    /// leg. A pose that does not fit the skeleton leaves the state unchanged.
    pub fn push(&mut self, skeleton: &Skeleton, pose: &Pose, dt_secs: f32) -> &[bool] {
        if pose.check(skeleton).is_err() || self.worlds.len() != skeleton.num_bones() {
            return self.planted();
        }
        forward_kinematics(skeleton, pose, &mut self.worlds);
        self.now_secs += f64::from(dt_secs.max(0.0));
        self.head = (self.head + 1) % RING;
        self.len = (self.len + 1).min(RING);
        self.times[self.head] = self.now_secs;
        for (f, leg) in self.legs.iter().enumerate() {
            for (j, bone) in contacts(leg).iter().enumerate() {
                if let Some(b) = bone {
                    self.positions[self.head][f * JOINTS_PER_FOOT + j] =
                        self.worlds[b.index()].translation;
                }
            }
        }
        self.positions[self.head][BODY] = body_position(&self.legs, &self.worlds);
        // The newest sample at least a window back (or the oldest one kept).
        let window = f64::from(self.settings.window_secs);
        let mut back = self.head;
        for k in 1..self.len {
            back = (self.head + RING - k) % RING;
            if self.now_secs - self.times[back] >= window {
                break;
            }
        }
        let elapsed = (self.now_secs - self.times[back]) as f32;
        let s = self.settings;
        if elapsed > 0.0 {
            let moved = self.positions[self.head][BODY] - self.positions[back][BODY];
            let speed = (moved - self.up * moved.dot(self.up)).length() / elapsed;
            let dt = dt_secs.max(0.0);
            self.pace = Some(match self.pace {
                Some(pace) => pace + (speed - pace) * dt / (PACE_SECS + dt),
                None => speed,
            });
        }
        for f in 0..self.legs.len() {
            let leg = self.legs[f];
            let h = s.height_ratio * leg.length;
            let v = slow_below(&s, &leg, self.pace.unwrap_or(0.0));
            let mut readings = [None; JOINTS_PER_FOOT];
            for (j, bone) in contacts(&leg).iter().enumerate() {
                if bone.is_none() {
                    continue;
                }
                let i = f * JOINTS_PER_FOOT + j;
                let p = self.positions[self.head][i];
                let speed = if elapsed > 0.0 {
                    (p - self.positions[back][i]).length() / elapsed
                } else {
                    f32::INFINITY
                };
                let height = p.dot(self.up);
                if speed < v {
                    self.grounds[i] = self.grounds[i].min(height);
                }
                readings[j] = Some(Reading {
                    height_above_ground: height - self.grounds[i],
                    speed,
                });
            }
            // Heights above grounds not known yet (no slow sample) read 0.
            let above = |r: &Reading| Some(r.height_above_ground).filter(|h| h.is_finite());
            self.heel_lifts[f] = readings[0].as_ref().and_then(above).unwrap_or(0.0);
            let lowest = (readings.iter().flatten().map(|r| above(r).unwrap_or(0.0)))
                .fold(f32::INFINITY, f32::min);
            self.lifts[f] = if lowest.is_finite() { lowest } else { 0.0 };
            let ball = readings[1].as_ref().or(readings[0].as_ref());
            let release = v * s.release_factor;
            self.ball_speeds[f] = ball.map_or(0.0, |r| r.speed / release.max(1e-9));
            if !self.ball_speeds[f].is_finite() {
                self.ball_speeds[f] = 0.0;
            }
            let was = self.planted[f];
            let mut now = next_state(was, &readings, h, v, s.release_factor);
            // A fresh plant is held for the shortest plant, so a jittery landing does not
            // flicker the lock.
            if was && !now && self.now_secs - self.planted_since[f] < f64::from(s.min_plant_secs) {
                now = true;
            }
            if now && !was {
                self.planted_since[f] = self.now_secs;
            }
            self.planted[f] = now;
            let scale = if now { s.release_factor } else { 1.0 };
            let held = |r: &Option<Reading>| r.as_ref().map(|r| holds(r, h, v, scale));
            self.contacts[f] = contact_of(held(&readings[0]), held(&readings[1]));
        }
        self.planted()
    }
}

/// Per-frame plant state of every leg over a clip.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantTrack {
    /// The legs, in column order.
    pub legs: Vec<Leg>,
    /// Frame-major: `planted[frame * legs.len() + leg]`.
    planted: Vec<bool>,
    /// The same layout: how high the foot stands above its ground, the least of its contact
    /// joints' heights above their grounds (source units, negative where the foot dips
    /// below). Zero in a track built from flags.
    lifts: Vec<f32>,
    /// The same for the heel (foot joint) alone.
    heel_lifts: Vec<f32>,
    /// The same for the ball (toes joint; the heel where the foot has none).
    ball_lifts: Vec<f32>,
    /// The same layout: which contacts of the foot hold ([`contact_of`]); `None` where neither
    /// does, it has no ball, or in a track built from flags.
    contacts: Vec<Option<Contact>>,
    /// An in-place clip's ground velocity under the body (source units per second): its
    /// standing feet slide back with it (`treadmill`). `None` for a clip that travels.
    belt: Option<Vec3>,
}

impl PlantTrack {
    /// A track from per-frame flags (frame-major, `legs.len()` per frame), e.g. the causal
    /// detector's outputs collected over a clip.
    pub fn from_flags(legs: Vec<Leg>, planted: Vec<bool>) -> PlantTrack {
        let lifts = vec![0.0; planted.len()];
        PlantTrack {
            legs,
            planted,
            heel_lifts: lifts.clone(),
            ball_lifts: lifts.clone(),
            contacts: vec![None; lifts.len()],
            lifts,
            belt: None,
        }
    }

    /// The ground's velocity under an in-place clip (its standing feet slide back with it, as
    /// on a treadmill), source units per second; `None` for a clip that travels.
    pub fn belt(&self) -> Option<Vec3> {
        self.belt
    }

    /// Number of frames.
    pub fn num_frames(&self) -> usize {
        self.planted.len().checked_div(self.legs.len()).unwrap_or(0)
    }

    /// The state of every leg at `frame` (empty past the end).
    pub fn frame(&self, frame: usize) -> &[bool] {
        let n = self.legs.len();
        self.planted.get(frame * n..(frame + 1) * n).unwrap_or(&[])
    }

    /// How high every leg's foot is above its ground at `frame` (empty past the end).
    pub fn lifts(&self, frame: usize) -> &[f32] {
        let n = self.legs.len();
        self.lifts.get(frame * n..(frame + 1) * n).unwrap_or(&[])
    }

    /// How high every leg's heel (foot joint) is above its ground at `frame`.
    pub fn heel_lifts(&self, frame: usize) -> &[f32] {
        let n = self.legs.len();
        self.heel_lifts
            .get(frame * n..(frame + 1) * n)
            .unwrap_or(&[])
    }

    /// How high every leg's ball (toes joint; the heel where the foot has none) is above its
    /// ground at `frame`.
    pub fn ball_lifts(&self, frame: usize) -> &[f32] {
        let n = self.legs.len();
        self.ball_lifts
            .get(frame * n..(frame + 1) * n)
            .unwrap_or(&[])
    }

    /// Which contacts of every leg's foot hold at `frame` ([`contact_of`]).
    pub fn contacts(&self, frame: usize) -> &[Option<Contact>] {
        let n = self.legs.len();
        self.contacts.get(frame * n..(frame + 1) * n).unwrap_or(&[])
    }

    /// Whether `leg` is planted at `frame`.
    pub fn is_planted(&self, frame: usize, leg: usize) -> bool {
        self.frame(frame).get(leg).copied().unwrap_or(false)
    }

    /// The plants of one leg as half-open frame ranges.
    pub fn intervals(&self, leg: usize) -> Vec<std::ops::Range<usize>> {
        let mut out = Vec::new();
        let mut start = None;
        for f in 0..self.num_frames() {
            match (self.is_planted(f, leg), start) {
                (true, None) => start = Some(f),
                (false, Some(s)) => {
                    out.push(s..f);
                    start = None;
                }
                _ => {}
            }
        }
        if let Some(s) = start {
            out.push(s..self.num_frames());
        }
        out
    }
}

/// Two-sided detection over a whole clip (`poses` of `skeleton`, `frame_time_secs` apart, `up`
/// the skeleton's up). Allocates; for files.
pub fn detect_clip(
    skeleton: &Skeleton,
    legs: &[Leg],
    poses: &[Pose],
    frame_time_secs: f32,
    up: Vec3,
    settings: &PlantSettings,
) -> PlantTrack {
    let legs: Vec<Leg> = legs.iter().copied().take(MAX_FEET).collect();
    let up = up.try_normalize().unwrap_or(Vec3::Y);
    let dt = frame_time_secs.max(1e-6);
    let c = ClipContacts::measure(skeleton, &legs, poses, up, dt, settings);
    let (nl, n) = (legs.len(), poses.len());
    let mut track = PlantTrack {
        planted: vec![false; nl * n],
        lifts: vec![0.0; nl * n],
        heel_lifts: vec![0.0; nl * n],
        ball_lifts: vec![0.0; nl * n],
        contacts: vec![None; nl * n],
        belt: c.belt,
        legs,
    };
    for f in 0..nl {
        let column = c.plants_of(f, &track.legs[f], settings);
        let mine: Vec<usize> = (0..c.joints.len())
            .filter(|&j| c.joints[j].0 == f)
            .collect();
        for (i, &planted) in column.iter().enumerate() {
            track.planted[i * nl + f] = planted;
            // How high the foot stands: the least of its contacts' heights above their grounds.
            let lift = (mine.iter().map(|&j| c.height(j, i))).fold(f32::INFINITY, f32::min);
            track.lifts[i * nl + f] = if lift.is_finite() { lift } else { 0.0 };
            // The heel is the leg's first contact.
            track.heel_lifts[i * nl + f] = c.height(mine[0], i);
            // The ball is its last (the heel again on a foot without one).
            track.ball_lifts[i * nl + f] = c.height(mine[mine.len() - 1], i);
            track.contacts[i * nl + f] = c.contact(&mine, i, &track.legs[f], planted, settings);
        }
    }
    track
}

/// The contact joints of a clip's legs measured over the whole clip: positions, two-sided
/// speeds, grounds, and (in place) the belt and how high a standing joint rides.
struct ClipContacts {
    /// (leg, bone) per contact joint.
    joints: Vec<(usize, BoneId)>,
    /// Joint-major: `pos[j * frames + i]`.
    pos: Vec<Vec3>,
    speeds: Vec<f32>,
    /// Per frame, the body's pace: its centred speed over the ground over [`PACE_SECS`].
    paces: Vec<f32>,
    grounds: Vec<f32>,
    /// Per joint, the height above its ground a standing joint may ride at (0: the leg's
    /// `height_ratio` alone).
    stance_band: Vec<f32>,
    belt: Option<Vec3>,
    frames: usize,
    up: Vec3,
    dt: f32,
}

impl ClipContacts {
    fn measure(
        skeleton: &Skeleton,
        legs: &[Leg],
        poses: &[Pose],
        up: Vec3,
        dt: f32,
        settings: &PlantSettings,
    ) -> ClipContacts {
        let n = poses.len();
        let joints: Vec<(usize, BoneId)> = (legs.iter().enumerate())
            .flat_map(|(f, l)| contacts(l).into_iter().flatten().map(move |b| (f, b)))
            .collect();
        let (pos, body) = contact_positions(skeleton, poses, legs, &joints);
        // Centred speeds over at least the window.
        let half = ((settings.window_secs / dt) / 2.0).ceil().max(1.0) as usize;
        // An in-place clip: judge the feet against the belt they stand on (`treadmill`).
        let mean_leg = legs.iter().map(|l| l.length).sum::<f32>() / legs.len().max(1) as f32;
        let view = Contacts {
            pos: &pos,
            frames: n,
            dt,
            half,
            up,
        };
        let belt = belt_velocity(&view, settings.speed_ratio * mean_leg);
        let speeds: Vec<f32> = (0..joints.len() * n)
            .map(|k| view.speed(k / n.max(1), k % n.max(1), belt))
            .collect();
        let pace_half = ((PACE_SECS / dt) / 2.0).round().max(half as f32) as usize;
        let paces = (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(pace_half), (i + pace_half).min(n - 1));
                let moved = body[b] - body[a];
                let flat = (moved - up * moved.dot(up)).length();
                flat / ((b - a).max(1) as f32 * dt)
            })
            .collect();
        let grounds: Vec<f32> = (joints.iter().enumerate())
            .map(|(j, &(f, _))| {
                let v = settings.speed_ratio * legs[f].length;
                let heights = (0..n).map(|i| (pos[j * n + i].dot(up), speeds[j * n + i]));
                clip_ground(heights, v)
            })
            .collect();
        let stance_band = (0..joints.len())
            .map(|j| match belt {
                Some(_) => stance_band(&view, j, grounds[j]),
                None => 0.0,
            })
            .collect();
        ClipContacts {
            joints,
            pos,
            speeds,
            paces,
            grounds,
            stance_band,
            belt,
            frames: n,
            up,
            dt,
        }
    }

    /// Which contacts of a foot of `leg` (its contact joints `mine`: heel, ball) hold at frame
    /// `i` ([`contact_of`]), judged as the plant rule judges them (`planted`: at the release
    /// thresholds).
    fn contact(
        &self,
        mine: &[usize],
        i: usize,
        leg: &Leg,
        planted: bool,
        s: &PlantSettings,
    ) -> Option<Contact> {
        let (h, v) = (
            s.height_ratio * leg.length,
            slow_below(s, leg, self.paces[i]),
        );
        let scale = if planted { s.release_factor } else { 1.0 };
        let held = |j: Option<&usize>| {
            j.map(|&j| {
                let r = Reading {
                    height_above_ground: self.height(j, i),
                    speed: self.speeds[j * self.frames + i],
                };
                holds(&r, h, v, scale)
            })
        };
        contact_of(held(mine.first()), held(mine.get(1)))
    }

    /// Height of joint `j` above its ground at frame `i`.
    fn height(&self, j: usize, i: usize) -> f32 {
        self.pos[j * self.frames + i].dot(self.up) - self.grounds[j]
    }

    /// Leg `f`'s plants, frame by frame: the hysteresis rule, then gaps the foot stayed
    /// through and short gaps closed, and short plants dropped.
    fn plants_of(&self, f: usize, leg: &Leg, settings: &PlantSettings) -> Vec<bool> {
        let h = settings.height_ratio * leg.length;
        let mine: Vec<usize> = (0..self.joints.len())
            .filter(|&j| self.joints[j].0 == f)
            .collect();
        let mut state = false;
        let mut column = vec![false; self.frames];
        for (i, slot) in column.iter_mut().enumerate() {
            let mut readings = [None; JOINTS_PER_FOOT];
            for (r, &j) in readings.iter_mut().zip(&mine) {
                // A joint riding higher while it stands (in place) is judged within its band.
                let scale = h / h.max(self.stance_band[j]);
                *r = Some(Reading {
                    height_above_ground: self.height(j, i) * scale,
                    speed: self.speeds[j * self.frames + i],
                });
            }
            let v = slow_below(settings, leg, self.paces[i]);
            state = next_state(state, &readings, h, v, settings.release_factor);
            *slot = state;
        }
        self.close_still_gaps(&mut column, &mine, leg, settings);
        let frames = |secs: f32| (secs / self.dt).round() as usize;
        close_gaps(&mut column, frames(settings.min_gap_secs));
        drop_short(&mut column, frames(settings.min_plant_secs));
        column
    }

    /// Gaps in a column where the foot never left its place become plants: a standing foot's
    /// jitter (a noisy capture's standing ball wobbles 1–2 cm from frame to frame, 0.5 m/s
    /// over the speed window) can break a plant the foot never lifted from. The foot stayed
    /// when some contact joint stays within the release height on every frame of the gap and
    /// every contact joint ends it where it began, give or take what a slow joint moves in
    /// that time. In place, standing is judged against the belt; gaps there stay.
    fn close_still_gaps(&self, column: &mut [bool], mine: &[usize], leg: &Leg, s: &PlantSettings) {
        if self.belt.is_some() {
            return;
        }
        let h = s.height_ratio * leg.length * s.release_factor;
        let flat = |v: Vec3| v - self.up * v.dot(self.up);
        for gap in runs(column, false) {
            if gap.start == 0 || gap.end == column.len() {
                continue;
            }
            // From the last planted frame to the first planted again.
            let (a, b) = (gap.start - 1, gap.end);
            let secs = (b - a) as f32 * self.dt;
            let slow = slow_below(s, leg, self.paces[a].min(self.paces[b]));
            let at = |j: usize, i: usize| self.pos[j * self.frames + i];
            let low = (a..=b).all(|i| mine.iter().any(|&j| self.height(j, i) < h));
            let stayed = mine
                .iter()
                .all(|&j| flat(at(j, b) - at(j, a)).length() < slow * secs);
            if low && stayed {
                column[gap].fill(true);
            }
        }
    }
}

/// World positions of `joints` over `poses`, joint-major (`[j * frames + i]`), and the body's
/// ([`body_position`] of `legs`) per frame; a pose that does not fit the skeleton leaves
/// zeros.
fn contact_positions(
    skeleton: &Skeleton,
    poses: &[Pose],
    legs: &[Leg],
    joints: &[(usize, BoneId)],
) -> (Vec<Vec3>, Vec<Vec3>) {
    let n = poses.len();
    let mut pos = vec![Vec3::ZERO; joints.len() * n];
    let mut body = vec![Vec3::ZERO; n];
    let mut worlds = vec![WorldTransform::IDENTITY; skeleton.num_bones()];
    for (i, p) in poses.iter().enumerate() {
        if p.check(skeleton).is_err() {
            continue;
        }
        forward_kinematics(skeleton, p, &mut worlds);
        for (j, &(_, b)) in joints.iter().enumerate() {
            pos[j * n + i] = worlds[b.index()].translation;
        }
        body[i] = body_position(legs, &worlds);
    }
    (pos, body)
}

/// A joint's ground over a clip: a low percentile of its heights on slow frames (where it
/// stands), so one glitched frame does not sink the ground; all frames when none is slow.
fn clip_ground(samples: impl Iterator<Item = (f32, f32)> + Clone, slow: f32) -> f32 {
    let mut heights: Vec<f32> = samples
        .clone()
        .filter(|&(_, v)| v < slow)
        .map(|(h, _)| h)
        .collect();
    if heights.is_empty() {
        heights = samples.map(|(h, _)| h).collect();
    }
    heights.sort_by(f32::total_cmp);
    heights.get(heights.len() / 50).copied().unwrap_or(0.0)
}

/// Runs of `false` shorter than `max_len` between two `true`s become `true`.
fn close_gaps(column: &mut [bool], max_len: usize) {
    for run in runs(column, false) {
        let inner = run.start > 0 && run.end < column.len();
        if inner && run.len() < max_len {
            column[run].fill(true);
        }
    }
}

/// Runs of `true` shorter than `min_len` become `false`.
fn drop_short(column: &mut [bool], min_len: usize) {
    for run in runs(column, true) {
        if run.len() < min_len {
            column[run].fill(false);
        }
    }
}

fn runs(column: &[bool], value: bool) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < column.len() {
        if column[i] == value {
            let s = i;
            while i < column.len() && column[i] == value {
                i += 1;
            }
            out.push(s..i);
        } else {
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_close_and_short_plants_drop() {
        let mut c = [
            true, true, false, true, true, true, false, false, false, true,
        ];
        close_gaps(&mut c, 2);
        assert_eq!(
            c,
            [true, true, true, true, true, true, false, false, false, true]
        );
        drop_short(&mut c, 2);
        assert_eq!(
            c,
            [true, true, true, true, true, true, false, false, false, false]
        );
    }

    #[test]
    fn hysteresis_keeps_a_plant_inside_the_looser_bounds() {
        let r = |h: f32, v: f32| {
            [
                Some(Reading {
                    height_above_ground: h,
                    speed: v,
                }),
                None,
            ]
        };
        // Between the plant and release thresholds: plants only if already planted.
        assert!(!next_state(false, &r(0.012, 0.1), 0.01, 0.2, 1.5));
        assert!(next_state(true, &r(0.012, 0.1), 0.01, 0.2, 1.5));
        assert!(!next_state(true, &r(0.016, 0.1), 0.01, 0.2, 1.5));
        assert!(!next_state(true, &r(0.001, 0.31), 0.01, 0.2, 1.5));
    }

    /// A heel standing on y = 0 for 30 frames at 120 Hz whose plant the hysteresis broke at
    /// frames 10..20, with what the foot did meanwhile.
    fn one_heel(during_gap: impl Fn(usize) -> Vec3) -> (ClipContacts, Leg) {
        let pos: Vec<Vec3> = (0..30)
            .map(|i| match i {
                10..20 => during_gap(i),
                // Where the gap ends is where the foot stands from then on.
                20.. => during_gap(19) * Vec3::new(1.0, 0.0, 1.0),
                _ => Vec3::ZERO,
            })
            .collect();
        let leg = Leg {
            kind: super::super::rig::LegKind::Hind,
            side: crate::analysis::Side::Left,
            limb: 0,
            upper: BoneId(0),
            lower: BoneId(1),
            foot: BoneId(2),
            toes: None,
            length: 0.8,
            carried: false,
        };
        let c = ClipContacts {
            joints: vec![(0, BoneId(2))],
            pos,
            speeds: vec![0.0; 30],
            paces: vec![1.0; 30],
            grounds: vec![0.0],
            stance_band: vec![0.0],
            belt: None,
            frames: 30,
            up: Vec3::Y,
            dt: 1.0 / 120.0,
        };
        (c, leg)
    }

    #[test]
    fn a_gap_the_foot_stayed_through_is_one_plant() {
        let settings = PlantSettings::default();
        let broken = || {
            let mut c = [true; 30];
            c[10..20].fill(false);
            c
        };
        // Jitter of 1.5 cm about where it stands: one plant.
        let (c, leg) = one_heel(|i| Vec3::new(if i % 2 == 0 { 0.015 } else { -0.015 }, 0.0, 0.0));
        let mut column = broken();
        c.close_still_gaps(&mut column, &[0], &leg, &settings);
        assert!(column.iter().all(|&p| p));
        // Lifted 10 cm and put back: a step on the spot, two plants.
        let (c, leg) = one_heel(|_| Vec3::new(0.0, 0.1, 0.0));
        let mut column = broken();
        c.close_still_gaps(&mut column, &[0], &leg, &settings);
        assert_eq!(column, broken());
        // Slid 10 cm along the ground in 1/12 s (1.2 m/s): two plants.
        let (c, leg) = one_heel(|i| Vec3::new(0.01 * (i - 9) as f32, 0.0, 0.0));
        let mut column = broken();
        c.close_still_gaps(&mut column, &[0], &leg, &settings);
        assert_eq!(column, broken());
    }

    #[test]
    fn the_ground_ignores_one_glitched_frame() {
        let mut s: Vec<(f32, f32)> = (0..200)
            .map(|i| (1.0 + 0.001 * (i % 3) as f32, 0.0))
            .collect();
        s[17] = (-5.0, 0.0);
        assert!((clip_ground(s.iter().copied(), 0.1) - 1.0).abs() < 0.003);
    }
}
