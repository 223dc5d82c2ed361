//! Foot locking on the target, after [`Mapping::apply`]: while the source's foot is planted,
//! the target's foot stays where it landed (position and heading) at its standing height (the
//! first frame of a clip pinned at once; offline, given the plants' heights, as far above it
//! as the source's foot stands above its ground, scaled, up to `MAX_LIFT_RATIO` of the leg):
//! flat on the floor, or, while the animation pitches it ball down (a toe-off), rolled onto
//! its ball, which stays where standing put it while the ankle rises (live too: the causal
//! detector gives the source heel's rise over its lowest contact; a foot whose toes are not
//! rigged has its ankle raised as far, straight up); a foot landing toes up comes down about
//! its heel, and one the performer turns turns with it (the root carried with it) about the
//! joint it stands on (its ball while the source's heel rises, else its own lower joint), so
//! that joint stays put; its leg solved with the two-bone IK; the hips come down when a leg
//! cannot reach; every switch blends (see `spring`); no foot joint goes below the target's
//! floor.
//!
//! ```text
//!  source pose ─▶ PlantDetector (causal) ─┐        (offline: a PlantTrack from detect_clip)
//!                                         ▼
//!  target pose ─FK─▶ fit to the standing posture: each foot pitched, the hips moved, by the
//!                     animation's typical stance gap (offline: medians over the clip;
//!                     live: learnt from the frames held so far)
//!               ─FK─▶ root carried onto the held feet: over the ground by their contacts'
//!                     slide in the animation (stride warping, `stride`; a foot rolling over
//!                     its ball does not slide), up by their ankles' gaps to their pinned
//!                     heights, so a held leg stays as retargeted (two feet down, or one
//!                     about to land: the height that turns those legs least, `pelvis`)
//!                     (live: brought back within `max_carry_ratio` legs of the performer's
//!                     while no foot stands, where moving the body turns no leg; while one
//!                     stands, at most a leg farther)
//!               ─FK─▶ per foot: where it should go = planted ? lock : animated (ankle, heading)
//!                     at a switch: offset = shown − that, in place and speed; it decays
//!                     goal = where it should go + offset
//!                     pinned: the foot rolled on its pin with the animation's pitch
//!                     (`Foot::roll`): on its ball while that is pitched lower than standing
//!                     (as its lift-off nears, known offline, live foreseen from the
//!                     source's ball rising, its ankle no lower than the
//!                     animation's: a foot that cannot keep its ball down there leaves the
//!                     floor early rather than bend the legs), else on its heel and stood
//!                     flat (ball pitched down to its standing
//!                     height, about the heel: the pin comes forward; offline no lower than
//!                     the source's ball stands over its own flat standing height, scaled:
//!                     a heel strike's toes come down as the performer's do), blended in
//!                     and out the same way; its heading (the way its ball points, or where
//!                     that points straight down its side axis's, `Foot::heading`) turned with the
//!                     animation's over the blends' half-life about the joint it stands on
//!                     (`turn_pins`, before the root is carried, which takes up the pin's
//!                     move; with plants given as flags alone: held, dragged past
//!                     `PIVOT_RAD` about the ball)
//!               ─▶ hips raised when every foot would have to be pulled up (the animation
//!                  sank the whole character)
//!                     floor: raise the goal so the heel stays above it; pitch the foot up
//!                     about the ankle so the ball does (offline, a swinging foot shares
//!                     that with lifting its ankle: `split_lift`, and a lifted swinging
//!                     goal moves over the ground to where its leg turns least:
//!                     `lift_aside`)
//!               ─▶ hips lowered by what the farthest pinned goal lacks (back up smoothly)
//!               ─FK─▶ two-bone IK per foot (skipped where the goal is the animated foot),
//!                     only as far as keeps each leg bone within 90° of the animation
//! ```
//! A lock is released when the source lifts the foot, or when the animated foot has left it
//! farther than `max_drift_ratio` leg lengths (a turn on the spot, a slide): the foot then
//! glides back to the animation instead of stretching the leg.

use glam::{Quat, Vec3};

use super::detect::{Contact, PlantDetector, PlantSettings, PlantTrack};
use super::ik::{solve_two_bone, TwoBoneSolution, MAX_EXTENSION};
use super::pelvis;
use super::rig::{find_contact_legs, find_legs, Leg, MAX_FEET};
use super::spring::Decay;
use super::stride::{FootStand, RootShift};
use crate::analysis::Analysis;
use crate::bounds::clamp_safe;
use crate::fk::{forward_kinematics, world_transforms, WorldTransform};
use crate::pose::Pose;
use crate::retarget::{FloorAt, Mapping};
use crate::skeleton::{BoneId, Skeleton};

mod fit;
mod floor;
mod foot;
mod foresight;
mod stances;

use fit::*;
use foot::*;
use foresight::*;
use stances::*;

/// How far (radians, ~26°) a planted foot's pinned heading may lag the animation's before it is
/// dragged along (a pivot on the spot).
const PIVOT_RAD: f32 = 0.45;

/// Half-life (seconds) of a pinned foot's heading catching up with the animation's
/// ([`FootLock::turn_pins`]): short, so a performer turning fast on a planted foot is followed
/// (CMU 131_01 turns one 0.8 rad in 12 frames at 120 Hz, and at the blends' half-life, 0.05 s,
/// the pin lagged it by up to 27°), yet not one frame, so the heading held as the foot landed,
/// or while no contact of the source's held, is caught up as a blend is, not in a snap.
/// Measured over the 152 walk/run pairs (`retarget_quality`'s locked_legs): the foot within
/// its bound on 54 of 84 at 0.05 s, 60 at this and 60 following at once; at once, foot_lock's
/// largest kick on the mannequin 1.57 -> 1.69 cm/frame².
const TURN_HALFLIFE_SECS: f32 = 0.015;

/// Highest a ball may be pitched up to, as a share of the foot's length (sin of ~64°): past
/// that the ankle lifts instead.
const MAX_BALL_RISE: f32 = 0.9;

/// Most the IK may turn either leg bone away from the animation (radians, 90°). A rig whose
/// upper bone is very short next to the lower (a Kinect-style hip joint at the pelvis centre)
/// would otherwise fold the leg right over to lift the foot a few centimetres; past this the
/// foot reaches its goal only part of the way.
const MAX_BONE_TURN: f32 = std::f32::consts::FRAC_PI_2;

/// Two-bone IK towards `goal`, going only as far along the way from `ankle` as keeps the
/// leg's bones within [`MAX_BONE_TURN`] of where they were (by bisection; nothing allocated).
fn solve_bounded(hip: Vec3, knee: Vec3, ankle: Vec3, goal: Vec3, pole: Vec3) -> TwoBoneSolution {
    let turn = |s: &TwoBoneSolution| {
        let upper = (knee - hip).angle_between(s.knee - hip);
        let lower = (ankle - knee).angle_between(s.ankle - s.knee);
        upper.max(lower)
    };
    let full = solve_two_bone(hip, knee, ankle, goal, pole);
    let t = turn(&full);
    if t.is_nan() || t <= MAX_BONE_TURN {
        return full;
    }
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    let mut best = solve_two_bone(hip, knee, ankle, ankle, pole);
    for _ in 0..10 {
        let mid = 0.5 * (lo + hi);
        let s = solve_two_bone(hip, knee, ankle, ankle.lerp(goal, mid), pole);
        if turn(&s) > MAX_BONE_TURN {
            hi = mid;
        } else {
            lo = mid;
            best = s;
        }
    }
    best
}

/// Highest a pinned foot follows the source's above its standing height, in leg lengths (8 mm
/// on a 1 m leg): a source foot standing a few millimetres up is followed; one farther up is
/// still landing, or stands on ground of its own, and the foot stays that close to the floor.
const MAX_LIFT_RATIO: f32 = 0.008;

/// A pinned foot is stood flat (its ball pitched to its standing height) in full while its
/// ankle-to-ball direction keeps at least this share of its length level; the flattening fades
/// out as it steepens to [`FLATTEN_FADE_LEVEL`] (a foot pointing straight down has no pitch
/// direction to speak of).
const FLATTEN_LEVEL: f32 = 0.5;
const FLATTEN_FADE_LEVEL: f32 = 0.2;

/// How much a direction keeping `level` of its length level tells of its way over the ground:
/// all of it from [`FLATTEN_LEVEL`] up, nothing at [`FLATTEN_FADE_LEVEL`] and below (smoothly
/// between). A foot pointing nearly straight down has no heading to speak of: the small
/// horizontal part of its way to the ball turns quickly, and flips as the ball passes under
/// the ankle.
fn level_weight(d: Vec3, up: Vec3) -> f32 {
    let level = (d - up * d.dot(up)).length() / d.length().max(1e-6);
    let k = ((level - FLATTEN_FADE_LEVEL) / (FLATTEN_LEVEL - FLATTEN_FADE_LEVEL)).clamp(0.0, 1.0);
    k * k * (3.0 - 2.0 * k)
}

/// How the lock behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LockSettings {
    /// Time a lock takes to blend in or out, seconds (the blend offset's half-life is half of
    /// it: after this long a quarter of the offset is left, after twice as long 3 %).
    pub blend_secs: f32,
    /// The same for a released foot catching up with the animation.
    pub release_secs: f32,
    /// A lock lets go when the animated foot is this many leg lengths away horizontally.
    pub max_drift_ratio: f32,
    /// The hips never come down (or, when every foot has sunk, go up) by more than this many
    /// leg lengths.
    pub max_drop_ratio: f32,
    /// Live, stride warping brings the root back within this many leg lengths over the ground
    /// of where the performer's motion puts it whenever no foot stands (moving the body then
    /// turns no leg), and while one stands carries it at most a leg farther: the character
    /// stays within about half a step of the performer's place between stances however long
    /// the walk (past the farther bound, the legs take up the rest of the stride's
    /// difference). Offline the character keeps its own stride's path: a
    /// character whose stride differs much (the Godot robot under LaFAN1's walk) would
    /// otherwise bend its standing legs until the locks let go.
    pub max_carry_ratio: f32,
    /// The live detector's thresholds.
    pub plants: PlantSettings,
}

impl Default for LockSettings {
    fn default() -> Self {
        LockSettings {
            blend_secs: 0.1,
            release_secs: 0.15,
            max_drift_ratio: 0.35,
            max_drop_ratio: 0.3,
            max_carry_ratio: 0.5,
            plants: PlantSettings::default(),
        }
    }
}

/// Foot locking for one performer (one mapping). Build once off the realtime path; per frame
/// [`FootLock::apply_live`] or [`FootLock::apply_planted`] allocate nothing.
#[derive(Debug, Clone)]
pub struct FootLock {
    source: Skeleton,
    target: Skeleton,
    detector: PlantDetector,
    feet: Vec<Foot>,
    goals: [Goal; MAX_FEET],
    root: Option<BoneId>,
    up: Vec3,
    floor: f32,
    settings: LockSettings,
    worlds: Vec<WorldTransform>,
    /// How far the hips came down last frame (an unpinned foot comes down with them).
    last_drop: f32,
    /// How much higher than needed the hips still are on their way back up.
    drop_offset: Decay<f32>,
    /// The root's move over the ground onto the standing feet ([`FootLock::carry_root`]).
    shift: RootShift,
    /// The root travels ([`Mapping::root_travels`]): stride warping may move it. An output
    /// asked for in place (or with a fixed root) keeps its root over its spot.
    carries: bool,
    /// Height added to the root on every frame ([`FootLock::fit_to_standing`]).
    root_fix: f32,
    /// The target's own posture is its rest and stands on its floor (its standing heights and
    /// foot pitch can be trusted).
    posture_stands: bool,
    /// The target's own rest stands on its own ground, along its own up, where that need not
    /// be this world's (a Z-up rest under a Y-up motion, whose floor the retarget cannot
    /// place): its feet's standing pitch can be trusted, their heights are the animation's.
    rest_feet_stand: bool,
    /// Source lengths to the target's (the mapping's root scale): what a source foot's lift is
    /// multiplied by.
    lift_scale: f32,
    /// A frame has been locked since the lock was built ([`FootLock::reset`] keeps it: the
    /// character was shown, so later plants blend from it).
    shown_once: bool,
    /// Live: how near each source foot's next plant is, and its lift-off.
    landing: LiveLanding,
    release: LiveRelease,
}

/// The angle of `d`'s way over the ground about `up` (from a fixed direction across it).
fn heading_about(up: Vec3, d: Vec3) -> f32 {
    let e1 = up.any_orthonormal_vector();
    let e2 = up.cross(e1);
    d.dot(e2).atan2(d.dot(e1))
}

/// The angle in (−π, π] equal to `a` modulo a turn.
fn wrap(a: f32) -> f32 {
    let t = std::f32::consts::TAU;
    a - t * ((a + std::f32::consts::PI) / t).floor()
}

impl FootLock {
    /// A lock for `mapping`'s target, driven by the plants of its root input. `source` and
    /// `target` are the analyses of those skeletons. `None` when the target has no standing
    /// legs or the mapping moves no root (nothing to lock against).
    pub fn new(
        mapping: &Mapping,
        source: &Analysis,
        target: &Analysis,
        settings: LockSettings,
    ) -> Option<FootLock> {
        let (up, floor, floor_at) = mapping.target_floor()?;
        let src_skel = mapping.source(mapping.root_input()?)?.clone();
        let tgt_skel = mapping.target().clone();
        // The source's feet are only watched: one hanging from elsewhere than its shin counts.
        let source_legs = find_contact_legs(&src_skel, source);
        let target_legs = find_legs(&tgt_skel, target);
        if target_legs.is_empty() {
            return None;
        }
        let aligned = world_transforms(&tgt_skel, &mapping.aligned_rest_pose());
        let own_rest = world_transforms(&tgt_skel, &tgt_skel.rest_pose());
        let own = (!target.used_pose).then_some(own_rest.as_slice());
        // Standing clearances from the character's own posture (it is authored standing; the
        // aligned rest shows the source's rest, whose feet need not be flat).
        let height = |b: BoneId| target.positions[b.index()].dot(target.up);
        // Clearances are measured from what the mapping's floor height belongs to: a joint's
        // standing height, the ground (0 in the character's own posture) under raised
        // contacts, or, not knowing, the lowest foot joint.
        let lowest = match floor_at {
            FloorAt::Joint(b) => height(b),
            FloorAt::Ground => 0.0,
            FloorAt::Unknown => target_legs
                .iter()
                .flat_map(|l| [Some(l.foot), l.toes])
                .flatten()
                .map(height)
                .fold(f32::INFINITY, f32::min),
        };
        let lift_scale = mapping.root_scale().unwrap_or(1.0);
        // The source's foot, ankle to ball, in its posture (0 without a ball).
        let source_foot = |l: &Leg| {
            let at = |b: BoneId| source.positions[b.index()];
            l.toes.map_or(0.0, |t| (at(t) - at(l.foot)).length())
        };
        // A character whose posture does not stand on its floor has no standing heights to
        // trust: live its feet learn them from the animation's stances, as offline's
        // `fit_to_standing` reads them off the animation. Not knowing the floor, the mapping
        // gives the source's scaled: the retargeted feet may stand far from it (LaFAN1 onto
        // Casual about 1 m under it). A posture read off a frame of the character's own
        // motion places its floor but says nothing of how its feet stand: pinned at that
        // frame's heights, the Bandai-Namco run rig stood its feet 2.6-15 cm off its ground
        // live, its thighs 5-9° mean off the performer's. A rest floating at the origin, or
        // standing along an up of its own, places no floor either: pinned at the rest's
        // heights, the pymo Meredith walk onto MakeHuman had its pins 9 cm under the
        // animation's standing ankles, the body carried down onto them and the swinging foot
        // lifted back over its floor, that thigh 15-22° off.
        let learns_heights = !mapping.target_posture_stands() || target.used_pose;
        let feet = target_legs
            .iter()
            .map(|leg| {
                let source = source_legs.iter().position(|s| s.key() == leg.key());
                let mut foot = standing_foot(leg, source, &aligned, own, target, up, lowest);
                foot.heel_reach = source.map_or(0.0, |s| lift_scale * source_foot(&source_legs[s]));
                foot.learns_heights = learns_heights;
                let own_floor = floor_at != FloorAt::Unknown && !target.used_pose;
                foot.rest_heel = (learns_heights && own_floor).then_some(foot.heel_clearance);
                foot
            })
            .collect();
        Some(FootLock {
            detector: PlantDetector::new(&src_skel, &source_legs, source.up, settings.plants),
            worlds: vec![WorldTransform::IDENTITY; tgt_skel.num_bones()],
            source: src_skel,
            target: tgt_skel,
            feet,
            goals: [Goal::default(); MAX_FEET],
            root: mapping.root_bone(),
            up,
            floor,
            settings,
            last_drop: 0.0,
            drop_offset: Decay::default(),
            shift: RootShift::default(),
            carries: mapping.root_travels(),
            root_fix: 0.0,
            // A posture read off a frame of the character's own motion (its rest folded along
            // one axis, as LaFAN1's and Bandai-Namco's BVH are) is a moment of a performance,
            // not how the character stands: the medoid frame of the Bandai run pitches its feet
            // 50-76° down, and fitting every frame to that tipped the retargeted feet as far.
            posture_stands: mapping.target_posture_stands() && !target.used_pose,
            rest_feet_stand: !target.used_pose && rest_on_own_ground(&target_legs, target),
            lift_scale,
            shown_once: false,
            landing: LiveLanding::default(),
            release: LiveRelease::default(),
        })
    }

    /// The source legs whose plants drive the lock (the order of [`FootLock::apply_planted`]'s
    /// flags and of [`FootLock::source_planted`]).
    pub fn source_legs(&self) -> &[Leg] {
        self.detector.legs()
    }

    /// The target legs that are locked.
    pub fn target_legs(&self) -> impl Iterator<Item = &Leg> {
        self.feet.iter().map(|f| &f.leg)
    }

    /// The live detector's current state per source leg.
    pub fn source_planted(&self) -> &[bool] {
        self.detector.planted()
    }

    /// Whether target foot `i` is held by a lock now.
    pub fn is_locked(&self, i: usize) -> bool {
        self.feet.get(i).is_some_and(|f| f.locked)
    }

    /// Forgets locks and the detector's history (a source restarted or seeked).
    pub fn reset(&mut self) {
        self.detector.reset();
        for f in &mut self.feet {
            f.locked = false;
            f.seen = false;
            f.position_offset = Decay::default();
            f.heading_offset = Decay::default();
            f.flat_offset = Decay::default();
            f.shown_flat = 0.0;
            f.landing = 0.0;
            f.aside = Decay::default();
            f.aside_wanted = Vec3::ZERO;
            f.animated_up_before = None;
            f.stance_heel = Moments::default();
        }
        self.shift = RootShift::default();
        self.landing = LiveLanding::default();
        self.release = LiveRelease::default();
        self.last_drop = 0.0;
        self.drop_offset = Decay::default();
    }

    /// Live: detects plants causally on `source` (the mapping's root input pose, a new sample
    /// `dt_secs` after the previous one when `new_sample`), then locks `out` (the target pose
    /// `apply` just wrote). Allocates nothing.
    pub fn apply_live(&mut self, source: &Pose, new_sample: bool, dt_secs: f32, out: &mut Pose) {
        if new_sample {
            self.detector.push(&self.source, source, dt_secs);
        }
        let mut planted = [false; MAX_FEET];
        for (p, s) in planted.iter_mut().zip(self.detector.planted()) {
            *p = *s;
        }
        // How much higher the source's heels stand than their feet's lowest contacts (how far
        // a foot rolls onto its ball). The foot itself is held on the floor, not as far above
        // it as the source's stands (offline): the causal ground is the lowest slow height
        // seen so far, which one dip of a foot lowers for good, so every later stance would
        // read a few millimetres up (the CMU walk onto X Bot: planted feet 0.71 cm up on half
        // their frames, 0.00 held on the floor).
        let mut lifts = Lifts::default();
        let measured = self.detector.heel_lifts().iter().zip(self.detector.lifts());
        for (l, (heel, foot)) in lifts.heel.iter_mut().zip(measured) {
            *l = heel - foot.max(0.0);
        }
        // Ahead of a plant the free foot comes down onto the height it will be pinned at, as
        // offline ([`landing_weight`]), when the source's heel is due on its ground within a
        // blend's time: a character whose retargeted foot hangs above the floor while the
        // performer's lands would otherwise be pinned up there and blended down while the
        // performer's already stands.
        if new_sample {
            let mut near = [0.0; MAX_FEET];
            for (n, leg) in near.iter_mut().zip(self.detector.legs()) {
                *n = self.settings.plants.height_ratio * leg.length;
            }
            let (legs, lead) = (self.detector.legs().len(), self.settings.blend_secs);
            let heights = self.detector.heel_lifts();
            let flags = &planted[..legs];
            (self.landing).update(flags, heights, &near[..legs], dt_secs, lead);
        }
        lifts.landing = self.landing.weight;
        // A pin on its ball rises to the retargeted ankle as its lift-off nears, as offline
        // ([`Foot::raise_to_animation`]), the lift-off foreseen from the source's ball rising.
        if new_sample {
            let mut high = [0.0; MAX_FEET];
            let p = self.settings.plants;
            for (h, leg) in high.iter_mut().zip(self.detector.legs()) {
                *h = p.release_factor * p.height_ratio * leg.length;
            }
            let legs = self.detector.legs().len();
            let (contacts, lows) = (self.detector.contacts(), self.detector.lifts());
            let speeds = self.detector.ball_speeds();
            let (flags, lead) = (&planted[..legs], self.settings.blend_secs);
            (self.release).update(
                flags,
                contacts,
                (lows, speeds),
                &high[..legs],
                dt_secs,
                lead,
            );
        }
        lifts.release = self.release.weight;
        for (p, s) in lifts.contact.iter_mut().zip(self.detector.contacts()) {
            *p = *s;
        }
        self.lock(&planted, Some(&lifts), dt_secs, true, out);
    }

    /// Offline: locks `out` with known plant flags per source leg (from [`super::detect_clip`]
    /// on the source clip), `dt_secs` after the previous frame. Allocates nothing.
    pub fn apply_planted(&mut self, planted: &[bool], dt_secs: f32, out: &mut Pose) {
        let mut flags = [false; MAX_FEET];
        for (p, s) in flags.iter_mut().zip(planted) {
            *p = *s;
        }
        self.lock(&flags, None, dt_secs, false, out);
    }

    /// Offline: [`FootLock::apply_planted`] with the flags of `frame` of `plants` (from
    /// [`super::detect_clip`] on the source clip), a pinned foot held as far above its
    /// standing height as the source's foot is above its ground (scaled): a source foot still
    /// settling or standing a few millimetres up is followed, not pressed onto the floor.
    /// Allocates nothing.
    ///
    /// An in-place source ([`PlantTrack::belt`]) is left alone: its standing feet slide back
    /// with the belt by design, and pinning them would drag the legs back under a body that
    /// never travels.
    pub fn apply_track(&mut self, plants: &PlantTrack, frame: usize, dt_secs: f32, out: &mut Pose) {
        if plants.belt().is_some() {
            return;
        }
        let mut flags = [false; MAX_FEET];
        for (p, s) in flags.iter_mut().zip(plants.frame(frame)) {
            *p = *s;
        }
        let mut lifts = Lifts::default();
        for (l, s) in lifts.foot.iter_mut().zip(plants.lifts(frame)) {
            *l = *s;
        }
        for (l, s) in lifts.heel.iter_mut().zip(plants.heel_lifts(frame)) {
            *l = *s;
        }
        let mut ball = [0.0; MAX_FEET];
        for (l, s) in ball.iter_mut().zip(plants.ball_lifts(frame)) {
            *l = *s;
        }
        lifts.ball = Some(ball);
        for (p, s) in lifts.contact.iter_mut().zip(plants.contacts(frame)) {
            *p = *s;
        }
        // The approach takes as long as a lock's blend would after the landing.
        let lead = if dt_secs > 0.0 {
            (self.settings.blend_secs / dt_secs).round() as usize
        } else {
            0
        };
        for (leg, l) in lifts.landing.iter_mut().enumerate().take(plants.legs.len()) {
            *l = landing_weight(plants, frame, leg, lead);
        }
        for (leg, l) in lifts.release.iter_mut().enumerate().take(plants.legs.len()) {
            *l = release_weight(plants, frame, leg, lead);
        }
        lifts.landing_flat = true;
        self.lock(&flags, Some(&lifts), dt_secs, false, out);
    }

    /// Locks `out`; `live`: no clip is known in advance, so the fit to the standing posture is
    /// learnt from this frame on, and the root is carried back within
    /// [`LockSettings::max_carry_ratio`] of where the performer's motion puts it whenever no
    /// foot stands ([`FootLock::carry_root`]).
    fn lock(
        &mut self,
        planted: &[bool; MAX_FEET],
        lifts: Option<&Lifts>,
        dt_secs: f32,
        live: bool,
        out: &mut Pose,
    ) {
        if out.check(&self.target).is_err() {
            return;
        }
        self.fk(out);
        let dt = dt_secs.max(0.0);
        self.take_lifts(lifts, dt);
        for f in &mut self.feet {
            if live {
                f.raise_limit(self.worlds[f.leg.foot.index()].translation.dot(self.up), dt);
            } else {
                f.raise_most = f32::INFINITY;
            }
        }
        self.learn_fit(planted, dt, live);
        self.apply_fit(out);
        self.turn_pins(planted, dt);
        for f in &mut self.feet {
            f.animated_up = self.worlds[f.leg.foot.index()].translation.dot(self.up);
        }
        self.carry_root(planted, dt, live, out);
        if live {
            // Live, a pin on its ball rises to the retargeted ankle where the body carries it
            // ([`Foot::raise_to_animation`]): the leg as retargeted from the body's place.
            // Raised to the uncarried ankle while the body stood carried down onto its
            // standing legs' pins, the pins drew their legs up by as much (Xia's walk onto the
            // Godot robot, the body 5.5 cm down: thigh 3.6 -> 14.2° p95 once the live lift-off
            // was foreseen by speed). Offline the same lost a pair (CMU run → Godot robot
            // thigh 7.8 -> 8.6° p95; the CMU run's pairs' thigh p95 up to 0.8° worse).
            for f in &mut self.feet {
                f.animated_up = self.worlds[f.leg.foot.index()].translation.dot(self.up);
            }
        }
        // Feet seen for the first time have no shown speed yet.
        let mut unseen = [false; MAX_FEET];
        for (u, f) in unseen.iter_mut().zip(&self.feet) {
            *u = !f.seen;
        }
        for i in 0..self.feet.len() {
            // A foot that has not learnt where it stands is not pinned to a floor unknown.
            let f = &self.feet[i];
            let wants = f.source.is_some_and(|s| planted[s]) && f.stands_known();
            self.goals[i] = self.foot_goal(i, wants, dt);
        }
        if self.raise_hips(out) {
            self.fk(out);
        }
        // The floor first (a locked goal lifted above it may need the hips lower), then again
        // after the hips came down: an unlocked foot moves down with them.
        for i in 0..self.feet.len() {
            self.clamp_to_floor(i, 0.0, live);
        }
        let drop = self.lower_hips(out, dt);
        self.last_drop = drop;
        if drop > 0.0 {
            self.fk(out);
        }
        for i in 0..self.feet.len() {
            self.clamp_to_floor(i, drop, live);
            self.step_aside(i, dt, live);
            let shown = if self.goals[i].active {
                self.solve_leg(i, out)
            } else {
                self.worlds[self.feet[i].leg.foot.index()].translation
            };
            self.shown_at(i, shown, dt, unseen[i]);
        }
        self.shown_once = true;
    }

    /// Takes this frame's source lifts into every foot: how high a pinned foot is held, its
    /// heel's pin and how far it may roll onto its ball.
    fn take_lifts(&mut self, lifts: Option<&Lifts>, dt: f32) {
        let halflife = 0.5 * self.settings.blend_secs;
        let follow = 1.0 - (-dt * std::f32::consts::LN_2 / halflife).exp();
        for i in 0..self.feet.len() {
            let length = self.feet[i].leg.length;
            let (foot, heel, landing, release, flat) = match (self.feet[i].source, lifts) {
                (Some(s), Some(l)) => (
                    l.foot[s],
                    Some(l.heel[s]),
                    l.landing[s],
                    l.release[s],
                    l.landing_flat,
                ),
                _ => (0.0, None, 0.0, 0.0, false),
            };
            let ball = (self.feet[i].source)
                .zip(lifts.and_then(|l| l.ball))
                .map(|(s, b)| b[s]);
            self.feet[i].ball_lift = (ball.zip(self.feet[i].ball_standing))
                .map(|(b, stand)| self.lift_scale * (b - stand).max(0.0));
            let contact = self.feet[i]
                .source
                .zip(lifts)
                .and_then(|(s, l)| l.contact[s]);
            self.feet[i].pivot = contact.map(|c| self.feet[i].pivot_of(c));
            self.feet[i].contact = contact;
            let on_ball = if contact == Some(Contact::Ball) {
                1.0
            } else {
                0.0
            };
            self.feet[i].on_ball += follow * (on_ball - self.feet[i].on_ball);
            self.feet[i].landing_before = self.feet[i].landing;
            self.feet[i].landing = landing;
            self.feet[i].release = release;
            self.feet[i].landing_flat = if flat { landing } else { 0.0 };
            let lift = clamp_safe(self.lift_scale * foot, 0.0, MAX_LIFT_RATIO * length);
            let rise = heel.map(|h| self.lift_scale * (h - foot.max(0.0)));
            self.feet[i].take_heel(lift, rise);
        }
    }

    /// Moves the root onto the feet held since the last frame (see [`super::stride`]), so a
    /// held foot's leg stays as retargeted instead of being bent to its pin: over the ground by
    /// what they slid in the animation (stride warping: the retarget scales the root's travel
    /// by the legs' ratio, and a rig whose legs are proportioned differently slides a standing
    /// foot), and up by how far their ankles are from their pinned heights (pelvis height);
    /// with two down, or one about to land, the height that turns those legs least
    /// ([`FootLock::body_height`]), each leg's IK taking up its share of their disagreement.
    /// A character with feet no source foot drives (a quadruped's front legs under a biped's
    /// walk) is only carried over the ground: moving its body up or down onto the driven feet
    /// would sink the others, which nothing stands on. `live`: brought back within
    /// [`LockSettings::max_carry_ratio`] while no foot stands, and never more than a leg past
    /// it (a foot standing holds it where its leg needs it: the limit enforced while a foot
    /// stood dropped the hips as the held leg reached back to its pin, thigh off by up to
    /// 28° in the release). `worlds` hold the animation and are brought up to
    /// date.
    fn carry_root(&mut self, planted: &[bool; MAX_FEET], dt: f32, live: bool, out: &mut Pose) {
        let Some(root) = self.root.filter(|_| self.carries) else {
            return;
        };
        let up = self.up;
        let mut stands = [FootStand::default(); MAX_FEET];
        let (mut limit, mut reach) = (f32::INFINITY, f32::INFINITY);
        let mut stance_reach = f32::INFINITY;
        for i in 0..self.feet.len() {
            let f = &self.feet[i];
            limit = limit.min(self.settings.max_drop_ratio * f.leg.length);
            if live {
                reach = reach.min(self.settings.max_carry_ratio * f.leg.length);
                // A stance carries the body over its foot by about a leg at most: while a
                // foot stands, the root may go that much farther (brought back once none does).
                let past = (self.settings.max_carry_ratio + 1.0) * f.leg.length;
                stance_reach = stance_reach.min(past);
            }
            let ankle = self.worlds[f.leg.foot.index()].translation;
            let ball = (f.leg.toes).map(|t| self.worlds[t.index()].translation - ankle);
            // The contact the foot stands on in the animation: the ankle, less what its roll
            // onto the ball moved it (a foot rolling over its ball does not slide).
            // Its way over the ground is the foot's heading ([`Foot::heading`]), not the
            // way to its ball, which flips as a toe-off points the foot straight down.
            let rotation = self.worlds[f.leg.foot.index()].rotation;
            let turn = wrap(self.heading(f, rotation) - self.ball_heading(f, rotation));
            let headed = ball.map(|o| Quat::from_axis_angle(up, turn) * o);
            let roll = headed.map_or(Vec3::ZERO, |o| f.roll(up, o));
            let contact = ankle - (roll - up * roll.dot(up));
            // Held since the last frame and still planted: the slide is the animation's.
            let held = f.source.is_some_and(|s| planted[s]) && f.locked && f.seen;
            // Live, where the pin stands over the ground from the animation's ankle, its ball
            // turned to the pin's heading (as the goal is).
            let pin_gap = (held && live).then(|| {
                let own = self.ball_heading(f, rotation);
                let turn = Quat::from_axis_angle(up, wrap(f.lock_heading - own));
                let d = f.pinned_ankle(up, self.floor, ball.map(|o| turn * o)) - ankle;
                d - up * d.dot(up)
            });
            stands[i] = FootStand {
                pin_gap,
                stands: held,
                // Less the pin's own move as it turned with the foot: the leg reaches it.
                slide: held.then(|| contact - f.raw_ankle - f.pin_moved),
                height_gap: if held {
                    (f.pinned_ankle(up, self.floor, ball) - ankle).dot(up)
                } else {
                    0.0
                },
            };
            self.feet[i].raw_ankle = contact;
        }
        if self.feet.iter().any(|f| f.source.is_none()) {
            limit = 0.0;
        }
        let height = self.body_height(planted, &stands, limit);
        // The body's height catches up with a change of the standing feet as slowly as a
        // released foot catches up with the animation: it carries the free foot with it.
        let halflife = [
            0.5 * self.settings.blend_secs,
            0.5 * self.settings.release_secs,
        ];
        let fresh = !self.shown_once;
        let n = self.feet.len();
        let limits = [limit, reach, stance_reach];
        (self.shift).update(&stands[..n], up, fresh, dt, halflife, limits, height);
        let shift = self.shift.ground + up * self.shift.height;
        if shift == Vec3::ZERO {
            return;
        }
        let parent = match self.target.parent(root) {
            Some(p) => self.worlds[p.index()].rotation,
            None => Quat::IDENTITY,
        };
        out.translations[root.index()] += parent.inverse() * shift;
        self.fk(out);
    }

    /// The body's height (its move up from the animation's) that keeps the legs of the held
    /// feet and of the feet about to land least turned from the animation ([`pelvis`]), with
    /// the share it takes: 1 while a foot is held, else the landing feet's weight. A landing
    /// foot counts by how near its plant is, its goal the height it will be pinned at: the
    /// body set by the standing foot alone (its toe-off rolling it down onto a ball that
    /// rises less than the performer's did, or a floor that is not flat under the capture)
    /// left the landing foot to be brought up to its pin by its own leg, bent away from the
    /// performer's, and the pinned leg bent again while the body caught up after the plant.
    /// `worlds` hold the animation.
    fn body_height(
        &self,
        planted: &[bool; MAX_FEET],
        stands: &[FootStand; MAX_FEET],
        limit: f32,
    ) -> Option<(f32, f32)> {
        let up = self.up;
        let mut legs = [pelvis::LegReach::default(); MAX_FEET];
        let mut k = 0;
        let (mut held, mut landing) = (false, 0.0f32);
        for (i, f) in self.feet.iter().enumerate() {
            let p = |b: BoneId| self.worlds[b.index()].translation;
            let ankle = p(f.leg.foot);
            let mut aside = Vec3::ZERO;
            let (gap, weight) = if stands[i].stands {
                held = true;
                // Where the pin stands over the ground from the ankle once the body is
                // carried (by last frame's carry, a stride's slide a frame from this one's):
                // a leg reaching a pin ahead or behind is straighter, and stiffer, than one
                // reaching straight down. Left out, the CMU walk's double stance at 3.3-3.7 s
                // live onto Casual (pins 3-5 cm over the ground from the carried ankles, the
                // hind foot on its toes) read the hind leg as bent and soft and gave it most
                // of the two feet's disagreement: its shin carried the live shin's p95.
                let ball = (f.leg.toes).map(|t| p(t) - ankle);
                let d = f.pinned_ankle(up, self.floor, ball) - ankle - self.shift.ground;
                aside = d - up * d.dot(up);
                (stands[i].height_gap, 1.0)
            } else if !f.locked {
                // Landing this frame (pinned below, held from the next; its weight is 0 now):
                // as much as it counted a frame ago, so the height does not jump back.
                let weight = if f.source.is_some_and(|s| planted[s]) {
                    f.landing_before
                } else {
                    f.landing
                };
                if !(weight > 0.0) {
                    continue;
                }
                landing = landing.max(weight);
                (self.pin_height(i, ankle, ankle) - ankle.dot(up), weight)
            } else {
                continue;
            };
            let (hip, knee) = (p(f.leg.upper), p(f.leg.lower));
            let pole = f.pole(
                [hip, knee, ankle],
                self.worlds[f.leg.upper.index()].rotation,
            );
            legs[k] = pelvis::LegReach {
                hip,
                knee,
                ankle,
                pole,
                gap,
                aside,
                weight,
                length: f.leg.length,
            };
            k += 1;
        }
        let h = pelvis::best_height(&legs[..k], up, limit)?;
        Some((h, if held { 1.0 } else { landing }))
    }

    /// Turns every pinned foot whose source's contacts are known and hold with the
    /// animation's heading, about the joint it stands on ([`Foot::pivot_of`],
    /// [`Foot::turn_about`]): the foot points as the performer's does (a held heading lagged
    /// it by up to [`PIVOT_RAD`], caught up only after the release), and that joint stays
    /// where it stood. The pin is taken at the heading shown as the foot lands, so the whole
    /// catching up happens here, about that joint: an offset blending the shown heading onto
    /// the animation's turned the foot about its ankle instead, sweeping its ball. What the
    /// turn moves the ankle over the ground is recorded for [`FootLock::carry_root`], so the
    /// root goes with it and the leg stays as retargeted (turning the pin alone moved the
    /// ankle the leg had to reach). `worlds` hold the animation.
    fn turn_pins(&mut self, planted: &[bool; MAX_FEET], dt: f32) {
        let (up, floor) = (self.up, self.floor);
        // The share of the way to the animation's heading the pin turns this frame
        // ([`TURN_HALFLIFE_SECS`]).
        let follow = 1.0 - (-dt * std::f32::consts::LN_2 / TURN_HALFLIFE_SECS).exp();
        for i in 0..self.feet.len() {
            self.feet[i].pin_moved = Vec3::ZERO;
            let f = &self.feet[i];
            let held = f.locked && f.source.is_some_and(|s| planted[s]);
            let Some(share) = f.pivot.filter(|_| held) else {
                continue;
            };
            let w = self.worlds[f.leg.foot.index()];
            let animated = self.heading(f, w.rotation);
            let turn = wrap(animated - f.lock_heading) * follow;
            if !(turn != 0.0) {
                continue;
            }
            let heading = wrap(f.lock_heading + turn);
            let ball = (f.leg.toes).map(|t| self.worlds[t.index()].translation - w.translation);
            let own = self.ball_heading(f, w.rotation);
            let ball_at = |h: f32| ball.map(|o| Quat::from_axis_angle(up, wrap(h - own)) * o);
            let balls = ball_at(f.lock_heading).zip(ball_at(heading));
            let f = &mut self.feet[i];
            let before = f.lock_position;
            f.turn_about(up, floor, heading, balls, share);
            f.pin_moved = f.lock_position - before;
        }
    }

    fn heading(&self, foot: &Foot, rotation: Quat) -> f32 {
        foot.heading(self.up, rotation)
    }

    /// The way from `foot`'s ankle to its ball over the ground (or, without one, a level axis
    /// of its rest): what a ball offset is turned from to stand at a heading.
    fn ball_heading(&self, foot: &Foot, rotation: Quat) -> f32 {
        heading_about(self.up, rotation * foot.heading_local)
    }

    /// Updates foot `i`'s lock state and returns where its ankle and rotation should go.
    fn foot_goal(&mut self, i: usize, wants: bool, dt: f32) -> Goal {
        let ankle_w = self.worlds[self.feet[i].leg.foot.index()];
        let animated = ankle_w.translation;
        let heading_now = self.heading(&self.feet[i], ankle_w.rotation);
        let ball_heading = self.ball_heading(&self.feet[i], ankle_w.rotation);
        let up = self.up;
        let flat = |v: Vec3| v - up * v.dot(up);
        let max_drift = self.settings.max_drift_ratio * self.feet[i].leg.length;
        let halflife = 0.5 * self.settings.blend_secs;
        let release_secs = self.settings.release_secs;
        let last_drop = self.last_drop;
        let shown_once = self.shown_once;
        let floor = self.floor;
        // The ball relative to the ankle, turned to a heading (the pin's).
        let ball_anim =
            (self.feet[i].leg.toes).map(|t| self.worlds[t.index()].translation - animated);
        let ball_at = |heading: f32| {
            ball_anim.map(|o| Quat::from_axis_angle(up, wrap(heading - ball_heading)) * o)
        };
        // A foot not seen yet is shown where the animation has it: before the settle below,
        // which measures from there (the rest pose it starts at may float far off the floor).
        let f = &mut self.feet[i];
        // Nothing shown yet at all (not after a reset): a plant pins without a blend.
        let fresh = !f.seen && !shown_once;
        if !f.seen {
            (f.shown_position, f.shown_heading) = (animated, heading_now);
            (f.animated_position, f.animated_heading) = (animated, heading_now);
            f.seen = true;
        }
        let settle = if wants && !self.feet[i].locked {
            self.landing_settle(i, self.feet[i].shown_position, animated)
        } else {
            0.0
        };
        // Ahead of a plant (known offline, foreseen live) the free foot is brought towards
        // the height it will be pinned at, so it stands when the source's does.
        let landing = self.feet[i].landing;
        let approach = if !wants && !self.feet[i].locked && landing > 0.0 {
            landing * (self.pin_height(i, animated, animated) - animated.dot(up))
        } else {
            0.0
        };
        let f = &mut self.feet[i];
        let (anim_velocity, anim_rate) = f.animation_moved(animated, heading_now, dt);
        let was = f.locked;
        if wants && !f.locked {
            // Pinned where the foot is shown as it lands (the animation's foot, or where an
            // earlier lock letting go still holds it): it stops there, without gliding on.
            // A foot landing on its ball is pinned where its heel will come down.
            f.locked = true;
            f.lock_heading = f.shown_heading;
            let roll = ball_at(f.lock_heading).map_or(Vec3::ZERO, |o| f.roll(up, o));
            f.lock_position = f.shown_position + up * settle - flat(roll);
        }
        let drift = flat(f.pinned_ankle(up, floor, ball_at(f.lock_heading)) - animated);
        if f.locked && (!wants || drift.length() > max_drift) {
            f.locked = false;
        }
        // Where the pin does not turn with the animation (plants given as flags alone, or no
        // contact of the source's holds) the heading stays pinned against small turns (stance
        // jitter), but a performer who pivots on a planted foot (turning on the spot) turns
        // it: past `PIVOT_RAD` the pin is dragged along on its ball, so the toes never point
        // far from the performer's.
        if f.locked && f.pivot.is_none() {
            let off = wrap(heading_now - f.lock_heading);
            if off.abs() > PIVOT_RAD {
                let heading = wrap(f.lock_heading + off - PIVOT_RAD.copysign(off));
                let (from, to) = (ball_at(f.lock_heading), ball_at(heading));
                f.turn_about(up, floor, heading, from.zip(to), 1.0);
            }
        }
        f.raised = 0.0;
        let (target, target_heading, velocity, rate) = if f.locked {
            let rolled = f.rolled_ankle(up, floor, ball_at(f.lock_heading));
            f.raised = f.raise_to_animation(up, rolled);
            let ankle = rolled + up * f.raised;
            (ankle, f.lock_heading, Vec3::ZERO, 0.0)
        } else {
            (
                animated + up * approach,
                heading_now,
                anim_velocity,
                anim_rate,
            )
        };
        if f.locked != was {
            let carried = if f.locked { 0.0 } else { last_drop };
            let goal = (target - up * carried, target_heading, velocity, rate);
            f.retake_offsets(fresh, up, goal, dt);
        }
        // A released foot catches up with the animation, which has lifted it already (the
        // live detector lets go a frame or two late): more slowly than a landing settles, or
        // the catching up shows as a kick.
        let halflife = if f.locked {
            halflife
        } else {
            0.5 * release_secs
        };
        f.position_offset.step(dt, halflife);
        f.heading_offset.step(dt, halflife);
        let ankle = target + f.position_offset.value;
        let heading = target_heading + f.heading_offset.value;
        let turn = wrap(heading - heading_now);
        if dt > 0.0 {
            f.shown_heading_rate = wrap(heading - f.shown_heading) / dt;
        }
        f.shown_heading = heading;
        let active = f.locked
            || approach != 0.0
            || f.position_offset.is_active()
            || f.heading_offset.is_active();
        let pinned = f.locked;
        let toes = f.leg.toes;
        let yaw = Quat::from_axis_angle(up, turn);
        let ball_offset = toes.map(|t| yaw * (self.worlds[t.index()].translation - animated));
        let mut goal = Goal {
            active,
            pinned,
            ankle,
            rotation: (yaw * ankle_w.rotation).normalize(),
            ball_offset,
            swinging: !wants,
            floor_lift: 0.0,
        };
        self.flatten(i, pinned != was, fresh, dt, &mut goal);
        goal
    }

    /// A pinned foot stands flat: its ball is pitched about the ankle to its standing height
    /// (the rest's, beside the heel's), as a planted foot is on the floor whatever pitch the
    /// source's foot joints give it (rigs build feet differently: a toe joint on the ground, or
    /// level with the ankle). The pitch blends in and out like the position: an offset taking
    /// up the difference at each switch, decaying.
    fn flatten(&mut self, i: usize, switched: bool, fresh: bool, dt: f32, goal: &mut Goal) {
        let (up, floor) = (self.up, self.floor);
        let halflife = 0.5 * self.settings.blend_secs;
        let f = &mut self.feet[i];
        let Some(o) = goal.ball_offset else { return };
        // Ahead of a known plant the ball comes down as the ankle does (`landing_flat`). A
        // pinned foot rolled onto its ball already stands it there.
        let weight = if goal.pinned { 1.0 } else { f.landing_flat };
        let now = (goal.ankle + o).dot(up);
        let wanted = weight * (f.ball_goal(floor, now) - now);
        if fresh {
            f.shown_flat = wanted;
        }
        if switched {
            f.flat_offset = Decay {
                value: f.shown_flat - wanted,
                velocity: 0.0,
            };
        }
        f.flat_offset.step(dt, halflife);
        let lift = wanted + f.flat_offset.value;
        f.shown_flat = lift;
        // A foot pointing (nearly) straight down has no pitch direction to speak of: its
        // horizontal part turns quickly, and pitching along it would swing the toes about. The
        // flattening fades out as the foot steepens.
        let len = o.length();
        let lift = lift * level_weight(o, up);
        if lift.abs() > 1e-6 {
            pitch_ball(goal, up, o.dot(up) + lift);
            goal.active = true;
        }
        // A pinned foot pitched toes up (landing on its heel) comes down onto its sole about
        // its heel, the point of the sole under the ankle where it stands: the pin comes
        // forward by how much less the ankle leans back over that point. Pitched about the
        // ankle joint alone, a rig whose ankle stands high over its toe joint (8 cm on X Bot)
        // would swing its toes over the ground as they come down.
        let Some(o) = goal.ball_offset else { return };
        let pitch = |rise: f32| (rise / len.max(1e-6)).clamp(-1.0, 1.0).asin();
        let toes_up = (pitch(o.dot(up)) - pitch(f.ball_clearance - f.heel_clearance)).max(0.0);
        if goal.pinned && !switched {
            let ahead = (o - up * o.dot(up)).normalize_or_zero();
            let shift = ahead * (f.heel_clearance.max(0.0) * (f.toes_up.sin() - toes_up.sin()));
            f.lock_position += shift;
            goal.ankle += shift;
        }
        f.toes_up = toes_up;
    }

    /// How far foot `i`, landing with its ankle at `ankle`, is from its standing height: its
    /// lowest contact (heel, or ball at the animation's offset from the heel) above or below its
    /// standing clearance. A plant puts it there: the source's foot is down. `animated` is the
    /// animated ankle.
    fn landing_settle(&self, i: usize, ankle: Vec3, animated: Vec3) -> f32 {
        let f = &self.feet[i];
        let up = self.up;
        let heel = ankle.dot(up);
        let ball =
            (f.leg.toes).map(|t| heel + (self.worlds[t.index()].translation - animated).dot(up));
        let (lowest, standing) = match ball {
            Some(b) if b - f.ball_clearance < heel - f.heel_clearance => (b, f.ball_clearance),
            _ => (heel, f.heel_clearance),
        };
        self.floor + standing - lowest
    }

    /// The height along up at which foot `i`'s ankle is pinned when it lands with its ankle at
    /// `ankle`: where the source's heel is known, its standing height plus the heel's lift, or,
    /// landing toes down, as high as stands its ball at its standing height at the animation's
    /// pitch (as [`Foot::roll`] stands a foot on its ball), never under its standing height;
    /// else its lowest contact settled onto its standing height, plus the foot's lift.
    fn pin_height(&self, i: usize, ankle: Vec3, animated: Vec3) -> f32 {
        let f = &self.feet[i];
        if !f.stands_known() {
            return ankle.dot(self.up);
        }
        match f.heel_lift {
            Some(h) => {
                let heel = self.floor + f.heel_clearance + h;
                // A foot landing toes down (the source's heel up) keeps the animation's pitch,
                // its ball on its standing height: the ankle as high as its own foot asks, not
                // as high as the performer's heel rises (scaled by the legs): a foot shorter
                // against its leg than the performer's, its ankle held that high, had its ball
                // pitched down onto the floor ahead of the plant, up to the 64° limit (Xia's
                // walk's final stop onto the pybvh test rig: 50-60° against the performer's
                // 20-26°).
                let ball = (f.leg.toes).filter(|_| f.heel_rise > 0.0).map(|t| {
                    let o = self.worlds[t.index()].translation - animated;
                    self.floor + f.ball_clearance + f.lift - o.dot(self.up)
                });
                let standing = self.floor + f.heel_clearance + f.lift;
                ball.map_or(heel, |b| b.max(standing))
            }
            None => ankle.dot(self.up) + self.landing_settle(i, ankle, animated) + f.lift,
        }
    }

    /// Records where foot `i` was shown this frame (for the next frame's velocities). `first`:
    /// the foot is shown for the first time, its speed not known (measured from the animated
    /// ankle it starts from, a foot the floor lifts read as moving up fast, and a plant on
    /// the next frame blended that speed in: Xia's walk onto X Bot, the first pinned foot
    /// thrown 7 cm up).
    fn shown_at(&mut self, i: usize, ankle: Vec3, dt: f32, first: bool) {
        let f = &mut self.feet[i];
        if first {
            f.shown_velocity = Vec3::ZERO;
        } else if dt > 0.0 {
            f.shown_velocity = (ankle - f.shown_position) / dt;
        }
        f.shown_position = ankle;
    }

    /// The target's world transforms of `out`, with every carried foot placed at its shin's
    /// end (in `out` too): a move of the root moves the legs but not a foot beside them.
    fn fk(&mut self, out: &mut Pose) {
        forward_kinematics(&self.target, out, &mut self.worlds);
        for i in 0..self.feet.len() {
            let Some(offset) = self.feet[i].carried else {
                continue;
            };
            let leg = self.feet[i].leg;
            let at = self.worlds[leg.lower.index()].transform_point(offset);
            let parent = self.parent_world(leg.foot);
            out.translations[leg.foot.index()] =
                parent.rotation.inverse() * (at - parent.translation);
            self.worlds[leg.foot.index()].translation = at;
        }
    }

    /// The world transform `bone` hangs from (identity for a root).
    fn parent_world(&self, bone: BoneId) -> WorldTransform {
        match self.target.parent(bone) {
            Some(p) => self.worlds[p.index()],
            None => WorldTransform::IDENTITY,
        }
    }

    /// Two-bone IK of foot `i` onto its goal; writes the upper, lower and foot rotations (and a
    /// carried foot's place) and returns where the ankle went.
    fn solve_leg(&mut self, i: usize, out: &mut Pose) -> Vec3 {
        let leg = self.feet[i].leg;
        let goal = self.goals[i];
        let w = |b: BoneId| self.worlds[b.index()];
        let (wu, wl, wf) = (w(leg.upper), w(leg.lower), w(leg.foot));
        let (hip, knee, ankle) = (wu.translation, wl.translation, wf.translation);
        // Nothing to do where the foot already is (a standing, held pose stays exact).
        let same_place = (goal.ankle - ankle).length() <= 1e-5 * leg.length;
        if same_place && goal.rotation.dot(wf.rotation).abs() >= 1.0 - 1e-7 {
            return ankle;
        }
        // The animation's own bend side; the remembered one when the leg is straight.
        let bend = bend_of(hip, knee, ankle);
        let pole = if bend.length() > STRAIGHT_BEND_RATIO * leg.length {
            self.feet[i].pole_local = (wu.rotation.inverse() * bend).normalize_or_zero();
            bend
        } else {
            wu.rotation * self.feet[i].pole_local
        };
        let s = solve_bounded(hip, knee, ankle, goal.ankle, pole);
        let parent_world = |b: BoneId| match self.target.parent(b) {
            Some(p) => self.worlds[p.index()].rotation,
            None => Quat::IDENTITY,
        };
        let upper_world = s.upper * wu.rotation;
        out.rotations[leg.upper.index()] =
            (parent_world(leg.upper).inverse() * upper_world).normalize();
        // Bones between upper and lower (twist bones) turn with the upper bone.
        let lower_parent = s.upper * parent_world(leg.lower);
        let lower_world = s.lower * s.upper * wl.rotation;
        out.rotations[leg.lower.index()] = (lower_parent.inverse() * lower_world).normalize();
        if self.feet[i].carried.is_some() {
            // Beside the body: the leg does not turn it; it goes where the shin now ends.
            let parent = self.parent_world(leg.foot);
            out.translations[leg.foot.index()] =
                parent.rotation.inverse() * (s.ankle - parent.translation);
            let turned = parent.rotation.inverse() * goal.rotation;
            out.rotations[leg.foot.index()] = turned.normalize();
            return s.ankle;
        }
        let foot_parent = s.lower * s.upper * parent_world(leg.foot);
        out.rotations[leg.foot.index()] = (foot_parent.inverse() * goal.rotation).normalize();
        s.ankle
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::Side;
    use crate::footplant::rig::LegKind;
    use floor::{lift_aside, split_lift};

    /// A left hind leg of bones 0 (thigh), 1 (shin), 2 (foot) and `toes`, `length` long.
    pub(super) fn left_leg(toes: Option<BoneId>, length: f32) -> Leg {
        Leg {
            kind: LegKind::Hind,
            side: Side::Left,
            limb: 0,
            upper: BoneId(0),
            lower: BoneId(1),
            foot: BoneId(2),
            toes,
            length,
            carried: false,
        }
    }

    #[test]
    fn a_landing_is_approached_only_after_a_swing() {
        let leg = left_leg(None, 1.0);
        // Planted 0-3, a 2-frame gap, 6-9, a 10-frame swing, 20-24.
        let flags: Vec<bool> = (0..25)
            .map(|f| f < 4 || (6..10).contains(&f) || f >= 20)
            .collect();
        let plants = PlantTrack::from_flags(vec![leg], flags);
        let w = |f: usize| landing_weight(&plants, f, 0, 4);
        // After the swing: nothing until four frames ahead, then rising to 1 the frame before.
        assert_eq!(w(15), 0.0);
        let ramp: Vec<f32> = (16..20).map(w).collect();
        assert!(ramp[0] > 0.0 && ramp[3] == 1.0, "{ramp:?}");
        assert!(ramp.windows(2).all(|p| p[0] < p[1]), "{ramp:?}");
        // Planted frames, and a gap shorter than twice the lead, are left alone.
        assert_eq!(w(2), 0.0);
        assert_eq!(w(20), 0.0);
        assert_eq!(w(4), 0.0);
        assert_eq!(w(5), 0.0);
        // No plant ahead within the clip.
        assert_eq!(landing_weight(&plants, 24, 0, 4), 0.0);
        assert_eq!(landing_weight(&plants, 17, 0, 0), 0.0);
    }

    #[test]
    fn a_release_is_foreseen_only_over_the_last_frames_of_a_plant() {
        let leg = left_leg(None, 1.0);
        // Planted 0-9, lifted 10-14, planted 15 to the clip's end.
        let flags: Vec<bool> = (0..20).map(|f| !(10..15).contains(&f)).collect();
        let plants = PlantTrack::from_flags(vec![leg], flags);
        let w = |f: usize| release_weight(&plants, f, 0, 4);
        // Nothing until four frames before the lift-off, then rising to 1 on the last
        // planted frame.
        assert_eq!(w(5), 0.0);
        let ramp: Vec<f32> = (6..10).map(w).collect();
        assert!(ramp[0] > 0.0 && ramp[3] == 1.0, "{ramp:?}");
        assert!(ramp.windows(2).all(|p| p[0] < p[1]), "{ramp:?}");
        // Lifted frames, and a plant that lasts to the clip's end (no lift-off known).
        assert_eq!(w(12), 0.0);
        assert_eq!(w(18), 0.0);
        assert_eq!(w(19), 0.0);
        assert_eq!(release_weight(&plants, 9, 0, 0), 0.0);
    }

    #[test]
    fn a_learnt_standing_height_keeps_the_rests_where_the_motion_confirms_it() {
        let dt = 1.0 / 60.0;
        // Stances alternating between two heights, a second each.
        let learn = |rest: Option<f32>, heights: [f32; 2]| {
            let mut foot = pinned_foot(true);
            foot.rest_heel = rest;
            for k in 0..600 {
                foot.learn_height(heights[(k / 60) % 2], dt);
            }
            foot.heel_clearance
        };
        // No rest height: the mean of the stances.
        assert!((learn(None, [0.07, 0.11]) - 0.09).abs() < 1e-4);
        // A rest height within the stances' spread of their mean (0.09 ± 0.02): the rest's.
        assert!((learn(Some(0.08), [0.07, 0.11]) - 0.08).abs() < 1e-4);
        // One more than twice their spread away (0.15 ± 0.01 against 0.08): the motion's.
        assert!((learn(Some(0.08), [0.14, 0.16]) - 0.15).abs() < 1e-4);
        // Between, between the two.
        let h = learn(Some(0.08), [0.09, 0.13]);
        assert!(h > 0.08 + 1e-3 && h < 0.11 - 1e-3, "{h}");
    }

    #[test]
    fn a_standing_pitch_learnt_live_is_the_mean_of_every_flat_frame() {
        let dt = 1.0 / 60.0;
        // Stances pitched alternately 0.1 and 0.3 rad, a second each, 4 s in all.
        let mut foot = pinned_foot(true);
        for k in 0..240 {
            foot.fit_secs += dt;
            foot.learn_standing_pitch([0.1, 0.3][(k / 60) % 2], dt);
        }
        // The mean of both, not the last second's (an average forgetting after a second
        // stood at 0.24 here).
        assert!(
            (foot.standing_pitch - 0.2).abs() < 1e-3,
            "{}",
            foot.standing_pitch
        );
    }

    #[test]
    fn a_live_lift_off_is_foreseen_from_the_ball_rising_on_a_toe_off() {
        let (dt, lead, high) = (1.0 / 60.0, 0.1, 0.05);
        let ball = Some(Contact::Ball);
        let step = |r: &mut LiveRelease, planted: bool, contact, low: f32| {
            r.update(&[planted], &[contact], (&[low], &[0.0]), &[high], dt, lead);
            r.weight[0]
        };
        // Standing flat, or on the toes with the ball still: nothing.
        let mut r = LiveRelease::default();
        for _ in 0..10 {
            assert_eq!(step(&mut r, true, Some(Contact::Flat), 0.0), 0.0);
        }
        for _ in 0..10 {
            assert_eq!(step(&mut r, true, ball, 0.002), 0.0);
        }
        // A toe-off: the ball rising at 0.2 m/s. Nothing while the release height is more
        // than `lead` away at that speed, then rising smoothly to 1 as the ball reaches it.
        let mut low = 0.002;
        let mut ramp = Vec::new();
        while low < high {
            low += 0.2 * dt;
            ramp.push((low, step(&mut r, true, ball, low)));
        }
        let far = |(l, _): &(f32, f32)| high - l > 0.2 * lead;
        assert!(
            ramp.iter().filter(|x| far(x)).all(|x| x.1 == 0.0),
            "{ramp:?}"
        );
        assert!(ramp.windows(2).all(|w| w[1].1 >= w[0].1), "{ramp:?}");
        assert_eq!(ramp.last().map(|x| x.1), Some(1.0), "{ramp:?}");
        // Read afresh every sample: a pause reads none (the raise's limit keeps the shown foot
        // from dropping at once); cleared when the foot lifts or its heel comes down.
        assert_eq!(step(&mut r, true, ball, low), 0.0);
        assert_eq!(step(&mut r, false, None, low + 0.01), 0.0);
        step(&mut r, true, ball, 0.0);
        step(&mut r, true, ball, 0.04);
        assert!(r.weight[0] > 0.0);
        assert_eq!(step(&mut r, true, Some(Contact::Flat), 0.04), 0.0);
    }

    /// A toe-off the detector lets go by speed: the ball pivots in place (its height held),
    /// then pushes off, its speed growing towards the speed a planted foot is let go at. The
    /// lift-off is read from how far that speed has come, and foreseen sooner from how fast it
    /// grows (before, nothing: the pins on their balls were never raised to the animation,
    /// Xia's released legs 10-11° off).
    #[test]
    fn a_live_lift_off_is_foreseen_from_the_ball_speeding_up() {
        let (dt, lead, high) = (1.0 / 60.0, 0.1, 0.05);
        let ball = Some(Contact::Ball);
        let step = |r: &mut LiveRelease, planted: bool, contact, speed: f32| {
            r.update(
                &[planted],
                &[contact],
                (&[0.002], &[speed]),
                &[high],
                dt,
                lead,
            );
            r.weight[0]
        };
        let smooth = |t: f32| t * t * (3.0 - 2.0 * t);
        // Standing on the ball, its speed steady at a third of the release speed: as far as
        // that speed has come, no more.
        let mut r = LiveRelease::default();
        step(&mut r, true, Some(Contact::Flat), 0.3);
        for _ in 0..10 {
            assert!((step(&mut r, true, ball, 0.3) - smooth(0.3)).abs() < 1e-6);
        }
        // Speeding up by 3 release speeds a second: at least the speed's own share, rising
        // to 1 as the ball reaches the release speed.
        let mut speed = 0.3;
        let mut ramp = Vec::new();
        while speed < 1.0 {
            speed += 3.0 * dt;
            ramp.push((speed, step(&mut r, true, ball, speed)));
        }
        assert!(
            ramp.iter().all(|&(s, w)| w >= smooth(s.min(1.0)) - 1e-6),
            "{ramp:?}"
        );
        assert!(ramp.windows(2).all(|w| w[1].1 >= w[0].1), "{ramp:?}");
        assert_eq!(ramp.last().map(|x| x.1), Some(1.0), "{ramp:?}");
        // Standing flat, a ball speeding up is no toe-off.
        let mut r = LiveRelease::default();
        for k in 0..30 {
            assert_eq!(step(&mut r, true, Some(Contact::Flat), 0.1 * k as f32), 0.0);
        }
    }

    /// A toe-off whose ball speeds up in steps, as Xia's does at 120 fps (0.34, 0.43, 0.48,
    /// 0.46, 0.46, 0.66 of the release speed, let go 0.06 s after its heel rose): its lift-off
    /// reads near from the first of them, as far as the ball's speed has come, not only from
    /// the steps' rates, and reads less again as a wandering ball slows (a stand on the toes
    /// held: its ball stays on the floor). Before, from the rates alone and ramped over the
    /// blends' time: 0.08-0.25 when the foot was let go, 0 on a steady speed.
    #[test]
    fn a_live_lift_off_is_read_from_how_fast_the_ball_moves() {
        let (dt, lead, high) = (1.0 / 120.0, 0.1, 0.05);
        let ball = Some(Contact::Ball);
        let step = |r: &mut LiveRelease, speed: f32| {
            r.update(&[true], &[ball], (&[0.005], &[speed]), &[high], dt, lead);
            r.weight[0]
        };
        let mut r = LiveRelease::default();
        step(&mut r, 0.25);
        let weights: Vec<f32> = [0.34, 0.43, 0.48, 0.46, 0.46, 0.66]
            .iter()
            .map(|&v| step(&mut r, v))
            .collect();
        assert!(weights[0] > 0.25, "{weights:?}");
        // Its share while the speed pauses; ahead of it as the speed jumps on (0.66 of the
        // release speed, 0.73 its share: at that rate the release is a sample away).
        assert!(weights[4] > 0.4 && weights[5] > 0.9, "{weights:?}");
        // The ball held at 0.8 of the release speed reads 0.9; slowing to a tenth, next to
        // nothing.
        let mut r = LiveRelease::default();
        step(&mut r, 0.8);
        assert!((step(&mut r, 0.8) - 0.896).abs() < 1e-3);
        assert!(step(&mut r, 0.1) < 0.03);
    }

    /// Live, the lift-off's foresight is read afresh every sample: what keeps the shown foot
    /// smooth is how fast its pin may rise, a leg length a second, or as fast as the animation
    /// lifts the ankle. Taken at once, a pin 14 cm under the animation's ankle (the Godot
    /// robot at the CMU 131_01 walk's final stand on its toes) rose most of it in a frame:
    /// foot_lock's kick 15.2 cm/frame² (1.28 in the animation).
    #[test]
    fn a_live_raise_rises_no_faster_than_a_leg_a_second_or_the_animation() {
        let (up, dt) = (Vec3::Y, 1.0 / 30.0);
        let mut foot = pinned_foot(true);
        ball_standing_flat(&mut foot);
        foot.take_heel(0.0, Some(0.04));
        (foot.on_ball, foot.release) = (1.0, 1.0);
        let pitched = ball_offset(0.15, 0.4, 0.1);
        let rolled = foot.rolled_ankle(up, 0.0, Some(pitched));
        // The animation's ankle held 14 cm over the pin's.
        foot.animated_up = rolled.y + 0.14;
        let most = RAISE_LEGS_PER_SEC * foot.leg.length * dt;
        let mut raises = Vec::new();
        for _ in 0..10 {
            foot.raise_limit(0.5, dt);
            foot.raised = foot.raise_to_animation(up, rolled);
            raises.push(foot.raised);
        }
        assert!((raises[0] - most).abs() < 1e-6, "{raises:?}");
        assert!(
            raises.windows(2).all(|w| w[1] - w[0] <= most + 1e-6),
            "{raises:?}"
        );
        assert!((raises[9] - 0.14).abs() < 1e-6, "{raises:?}");
        // An animation lifting its ankle 5 leg lengths a second lets the pin rise as fast.
        foot.raised = 0.0;
        foot.animated_up = rolled.y + 0.5;
        let fast = 5.0 * foot.leg.length * dt;
        foot.raise_limit(0.5 + fast, dt);
        let r = foot.raise_to_animation(up, rolled);
        assert!((r - fast).abs() < 1e-5, "{r} {fast}");
    }

    #[test]
    fn a_live_landing_is_foreseen_from_the_heel_coming_down_after_a_swing() {
        let (dt, lead, near) = (1.0 / 60.0, 0.1, 0.04);
        let mut l = LiveLanding::default();
        let step = |l: &mut LiveLanding, planted: bool, heel: f32| {
            l.update(&[planted], &[heel], &[near], dt, lead);
            l.weight[0]
        };
        // A foot shuffling low (never up past `near`) is not foreseen landing.
        step(&mut l, true, 0.0);
        for k in 1..10 {
            assert_eq!(step(&mut l, false, 0.002 * k as f32), 0.0);
        }
        for k in (0..10).rev() {
            assert_eq!(step(&mut l, false, 0.002 * k as f32), 0.0);
        }
        // Up to 20 cm and down at 1 m/s: nothing while the ground is more than `lead` away,
        // then rising smoothly to 1 as the heel reaches it.
        let mut heel = 0.0;
        while heel < 0.2 {
            heel += 0.01;
            assert_eq!(step(&mut l, false, heel), 0.0);
        }
        let mut ramp = Vec::new();
        while heel > 1e-4 {
            heel = (heel - 1.0 * dt).max(0.0);
            ramp.push((heel, step(&mut l, false, heel)));
        }
        let due = |(h, _): &(f32, f32)| *h > 1.0 * lead;
        assert!(
            ramp.iter().filter(|r| due(r)).all(|r| r.1 == 0.0),
            "{ramp:?}"
        );
        assert!(ramp.windows(2).all(|w| w[1].1 >= w[0].1), "{ramp:?}");
        assert!(ramp.windows(2).all(|w| w[1].1 - w[0].1 < 0.5), "{ramp:?}");
        assert_eq!(ramp.last().map(|r| r.1), Some(1.0), "{ramp:?}");
        // Held while the heel waits just over the ground; a plant clears it.
        assert_eq!(step(&mut l, false, 0.0), 1.0);
        assert_eq!(step(&mut l, true, 0.0), 0.0);
        // A heel bobbing up a few millimetres just over its ground keeps it; one rising again
        // past `near` (the swing goes on) fades it out.
        let mut l = LiveLanding {
            lift: [0.01; MAX_FEET],
            swung: [true; MAX_FEET],
            weight: [1.0; MAX_FEET],
        };
        for k in 1..5 {
            assert_eq!(step(&mut l, false, 0.01 + 0.005 * k as f32), 1.0);
        }
        let fading: Vec<f32> = (1..8)
            .map(|k| step(&mut l, false, near + 0.01 * k as f32))
            .collect();
        assert!(
            fading.windows(2).all(|w| w[1] < w[0]) && fading[6] < 0.3,
            "{fading:?}"
        );
    }

    /// A pinned foot standing on a floor at 0 with up +Y, built as X Bot's is: its ankle
    /// 8 cm up, and with `toes` a ball 2 cm up and 15 cm ahead (heading +X); without, a foot
    /// whose toes are not rigged, its ankle the lowest joint (2 cm up), whose performer's
    /// foot is 12 cm long.
    fn pinned_foot(toes: bool) -> Foot {
        let leg = left_leg(toes.then_some(BoneId(3)), 0.9);
        let (heel, ball, len) = if toes {
            (0.08, 0.02, 0.15)
        } else {
            (0.02, 0.0, 0.0)
        };
        let ankle = Vec3::new(0.3, heel, -0.2);
        let mut foot = Foot {
            heel_clearance: heel,
            ball_clearance: ball,
            foot_length: len,
            locked: true,
            heel_reach: if toes { 0.0 } else { 0.12 },
            seen: true,
            ..Foot::unlocked_at(leg, Some(0), ankle)
        };
        foot.take_heel(0.0, Some(0.0));
        foot
    }

    /// A foot pinned where it is shown keeps no speed up onto its pin: only a foot above its
    /// pin and coming down keeps its speed down (it settles instead of stopping in the air).
    /// A foot shown a hair under its pin and moving up was given its upward speed, and the
    /// spring carried it past the pin: live, Xia's walk onto X Bot, whose first frame read the
    /// floor's lift as a speed of 5 m/s, threw its first pinned foot 7 cm up.
    #[test]
    fn a_pinned_foot_keeps_only_a_speed_down_onto_its_pin() {
        let up = Vec3::Y;
        let pin = Vec3::new(0.3, 0.08, -0.2);
        let offset_after = |shown: Vec3, speed: Vec3| {
            let mut foot = pinned_foot(true);
            (foot.shown_position, foot.shown_velocity) = (shown, speed);
            foot.retake_offsets(false, up, (pin, 0.0, Vec3::ZERO, 0.0), 1.0 / 60.0);
            let kept = foot.position_offset.velocity;
            let mut highest = f32::NEG_INFINITY;
            for _ in 0..30 {
                foot.position_offset.step(1.0 / 60.0, 0.05);
                highest = highest.max(foot.position_offset.value.y);
            }
            (kept, highest)
        };
        // A hair under the pin, moving up fast: stopped there, never carried over it.
        let (v, highest) = offset_after(pin - up * 1e-6, up * 5.0);
        assert_eq!(v, Vec3::ZERO);
        assert!(highest < 1e-3, "carried {highest} m over its pin");
        // Above it and coming down: it keeps coming down.
        let (v, _) = offset_after(pin + up * 0.02, -up * 0.5);
        assert!(v.y < -0.4, "{v}");
        // Above it and moving up: stopped.
        let (v, _) = offset_after(pin + up * 0.02, up * 0.5);
        assert_eq!(v, Vec3::ZERO);
    }

    /// The ball's offset from the ankle of a foot heading `heading` (radians about +Y from
    /// +X), pitched so the ball stands `drop` below the ankle.
    fn ball_offset(len: f32, heading: f32, drop: f32) -> Vec3 {
        let reach = (len * len - drop * drop).sqrt();
        Vec3::new(heading.cos() * reach, -drop, -heading.sin() * reach)
    }

    /// Where the ball of `pinned_foot(true)` stands when the animation holds the foot flat,
    /// heading 0.4 rad: the point the tests of a rising foot expect to stay put.
    fn ball_standing_flat(foot: &mut Foot) -> Vec3 {
        let flat_ball = ball_offset(0.15, 0.4, 0.06);
        foot.pinned_ankle(Vec3::Y, 0.0, Some(flat_ball)) + flat_ball
    }

    fn flat(v: Vec3) -> Vec3 {
        Vec3::new(v.x, 0.0, v.z)
    }

    #[test]
    fn a_toeless_foot_rises_with_the_source_heel_straight_up_as_far_as_its_foot_reaches() {
        let up = Vec3::Y;
        let mut foot = pinned_foot(false);
        let standing = foot.pinned_ankle(up, 0.0, None);
        assert!(
            (standing - foot.lock_position).length() < 1e-6,
            "{standing}"
        );
        // The performer's heel 5 cm over its toes (a toe-off), the foot 3 mm up.
        foot.take_heel(0.003, Some(0.05));
        let risen = foot.pinned_ankle(up, 0.0, None);
        assert!(
            (flat(risen - standing)).length() < 1e-6,
            "{risen} {standing}"
        );
        assert!(((risen - standing).y - 0.053).abs() < 1e-6, "{risen}");
        // No higher than the performer's foot is long (12 cm): past that it is no toe-off.
        foot.take_heel(0.0, Some(0.3));
        let most = foot.pinned_ankle(up, 0.0, None);
        assert!(((most - standing).y - 0.12).abs() < 1e-6, "{most}");
        // A heel below the toes (a heel strike) does not sink it; one not known leaves it on
        // its pin, lifted with the foot.
        foot.take_heel(0.0, Some(-0.04));
        assert!((foot.pinned_ankle(up, 0.0, None) - standing).length() < 1e-6);
        foot.take_heel(0.002, None);
        let lifted = foot.pinned_ankle(up, 0.0, None) - standing;
        assert!((lifted - up * 0.002).length() < 1e-6, "{lifted}");
    }

    #[test]
    fn a_foot_pointing_straight_down_keeps_the_heading_its_side_axis_gives() {
        let up = Vec3::Y;
        // Heading +X, side axis +Z (ahead × up); pitched `down` degrees toes down, then
        // turned `turn` radians about up.
        let foot = pinned_foot(true);
        let pose = |down: f32, turn: f32| {
            Quat::from_axis_angle(up, turn) * Quat::from_axis_angle(Vec3::Z, -down.to_radians())
        };
        let level = foot.heading(up, pose(0.0, 0.0));
        assert!((level - heading_about(up, Vec3::X)).abs() < 1e-6);
        // Past straight down the way to the ball flips (its toes now point back under the
        // ankle); the foot's heading does not, and it still turns with the foot.
        for turn in [0.0f32, 0.5, -2.0] {
            let flipped = pose(95.0, turn) * foot.heading_local;
            let ball_way = wrap(heading_about(up, flipped) - level - turn);
            assert!(
                (ball_way.abs() - std::f32::consts::PI).abs() < 1e-4,
                "{ball_way}"
            );
            for down in [80.0, 90.0, 95.0, 100.0] {
                let h = foot.heading(up, pose(down, turn));
                assert!(wrap(h - level - turn).abs() < 1e-4, "{down}° {turn}: {h}");
            }
        }
        // A level foot (here 40° down and rolled 25° about its length, which tilts its side
        // axis) heads the way to its ball.
        let rolled = pose(40.0, 0.3) * Quat::from_axis_angle(Vec3::X, 0.44);
        let ball_way = heading_about(up, rolled * foot.heading_local);
        assert!((foot.heading(up, rolled) - ball_way).abs() < 1e-6);
        // In between, between the two, without a jump.
        let headings: Vec<f32> = (60..=85)
            .map(|d| {
                wrap(
                    foot.heading(
                        up,
                        pose(d as f32, 0.0) * Quat::from_axis_angle(Vec3::X, 0.44),
                    ) - level,
                )
            })
            .collect();
        assert!(
            headings.windows(2).all(|w| (w[1] - w[0]).abs() < 0.05),
            "{headings:?}"
        );
    }

    #[test]
    fn a_foot_rising_onto_its_ball_keeps_the_ball_where_it_stood() {
        let up = Vec3::Y;
        let mut foot = pinned_foot(true);
        let stood = ball_standing_flat(&mut foot);
        assert!((stood.y - 0.02).abs() < 1e-6, "{stood}");
        // The performer's heel 4 cm over its toes, the animation's foot pitched so: the ankle
        // rises 4 cm and comes towards the ball, which stays put.
        foot.take_heel(0.0, Some(0.04));
        let pitched = ball_offset(0.15, 0.4, 0.1);
        let ankle = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!((ankle.y - 0.12).abs() < 1e-5, "{ankle}");
        assert!(
            (ankle + pitched - stood).length() < 1e-5,
            "{} {stood}",
            ankle + pitched
        );
    }

    #[test]
    fn a_pinned_ball_comes_down_no_lower_than_the_source_ball_stands() {
        let mut foot = pinned_foot(true);
        // Its ball stands 2 cm over the floor at 0.1. Not knowing the source's ball: stood
        // flat from above and below.
        assert!((foot.ball_goal(0.1, 0.15) - 0.12).abs() < 1e-6);
        assert!((foot.ball_goal(0.1, 0.11) - 0.12).abs() < 1e-6);
        // The source's ball 3 cm over its flat standing height (a heel strike, the toes still
        // coming down): a ball up to that high stays where the animation has it, one higher
        // comes down to it, one under its standing height is still brought up.
        foot.ball_lift = Some(0.03);
        assert!((foot.ball_goal(0.1, 0.14) - 0.14).abs() < 1e-6);
        assert!((foot.ball_goal(0.1, 0.2) - 0.15).abs() < 1e-6);
        assert!((foot.ball_goal(0.1, 0.11) - 0.12).abs() < 1e-6);
        // The source's ball down: stood flat.
        foot.ball_lift = Some(0.0);
        assert!((foot.ball_goal(0.1, 0.14) - 0.12).abs() < 1e-6);
    }

    #[test]
    fn a_foot_leaving_its_ball_is_raised_to_the_animation_as_its_lift_off_nears() {
        let up = Vec3::Y;
        let mut foot = pinned_foot(true);
        let stood = ball_standing_flat(&mut foot);
        // On its ball, the animation's foot pitched so its ball is 10 cm under the ankle; the
        // performer's heel 4 cm up: the pin's ankle 12 cm up, its ball where it stood.
        foot.take_heel(0.0, Some(0.04));
        foot.on_ball = 1.0;
        let pitched = ball_offset(0.15, 0.4, 0.1);
        let rolled = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!((rolled.y - 0.12).abs() < 1e-5, "{rolled}");
        // The retargeted ankle stands 3 cm higher (a foot that raises its ankle less than
        // the performer's as it rolls): left there until the lift-off nears.
        foot.animated_up = 0.15;
        assert!((foot.pinned_ankle(up, 0.0, Some(pitched)) - rolled).length() < 1e-6);
        // On the last frame before it, at the animation's height, straight up: the ball keeps
        // its place over the ground and leaves the floor by as much.
        foot.release = 1.0;
        let raised = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!((raised.y - 0.15).abs() < 1e-5, "{raised}");
        assert!((flat(raised + pitched) - flat(stood)).length() < 1e-5);
        // Half way there on the ball, half the way.
        foot.on_ball = 0.5;
        let ankle = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!(ankle.y > 0.10 && ankle.y < 0.15, "{ankle}");
        // Never down: an animation lower than the pin leaves it.
        foot.on_ball = 1.0;
        foot.animated_up = 0.05;
        assert!((foot.pinned_ankle(up, 0.0, Some(pitched)) - rolled).length() < 1e-6);
        // A raised pin's ball stays as high as the raise put it, and one still under its
        // standing height (a foot only partly rolled onto its ball) is pitched up to that
        // height raised: the raise lifts its ball as it lifts its ankle.
        foot.raised = 0.03;
        assert!((foot.ball_goal(0.0, 0.05) - 0.05).abs() < 1e-6);
        assert!((foot.ball_goal(0.0, 0.08) - 0.05).abs() < 1e-6);
        assert!((foot.ball_goal(0.0, 0.03) - 0.05).abs() < 1e-6);
    }

    #[test]
    fn a_foot_on_its_ball_rolls_as_far_as_its_own_length_asks() {
        let up = Vec3::Y;
        let mut foot = pinned_foot(true);
        let stood = ball_standing_flat(&mut foot);
        // The animation pitches the foot so its ball is 10 cm under the ankle (4 cm of rise
        // past standing), the performer's shorter foot raising its heel only 2 cm.
        foot.take_heel(0.0, Some(0.02));
        let pitched = ball_offset(0.15, 0.4, 0.1);
        // While the source's heel and ball both hold, only as far as the heel rises: the
        // ball is left 2 cm low (the flattening then pitches it up).
        let ankle = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!((ankle.y - 0.10).abs() < 1e-5, "{ankle}");
        // Standing on its ball alone, fully: the ball stays where it stood, the pitch kept.
        foot.on_ball = 1.0;
        let ankle = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!((ankle.y - 0.12).abs() < 1e-5, "{ankle}");
        let ball = ankle + pitched;
        assert!((ball - stood).length() < 1e-5, "{ball} {stood}");
        // Half way through the blend, half the way.
        foot.on_ball = 0.5;
        let ankle = foot.pinned_ankle(up, 0.0, Some(pitched));
        assert!((ankle.y - 0.11).abs() < 1e-5, "{ankle}");
    }

    #[test]
    fn a_pinned_foot_turns_about_the_point_it_stands_on() {
        let up = Vec3::Y;
        // Heel (0), ball (1) and the sole's middle; standing flat and risen onto its ball;
        // and on its ball raised 3 cm towards the animation's ankle as its lift-off nears (the
        // raise lifts ankle and ball alike: the ball stays where it stood over the ground).
        let cases = [
            (1.0, 0.0, 0.0),
            (0.0, 0.0, 0.0),
            (0.5, 0.0, 0.0),
            (1.0, 0.04, 0.0),
        ];
        for (share, rise, raise) in cases.into_iter().chain([(1.0, 0.04, 0.03)]) {
            let mut foot = pinned_foot(true);
            foot.take_heel(0.0, Some(rise));
            if raise > 0.0 {
                (foot.on_ball, foot.release) = (1.0, 1.0);
                foot.animated_up = 0.08 + rise + raise;
            }
            let drop = 0.06 + rise;
            let (from, to) = (0.2f32, -0.3f32);
            let (o_from, o_to) = (ball_offset(0.15, from, drop), ball_offset(0.15, to, drop));
            // The point of the sole `share` of the way from the heel (under the ankle) to the
            // ball, over the ground.
            let point = |foot: &Foot, o: Vec3| {
                let ankle = foot.pinned_ankle(up, 0.0, Some(o));
                let heel = ankle - flat(foot.roll(up, o));
                flat(heel + (ankle + o - heel) * share)
            };
            let before = point(&foot, o_from);
            let heel_before = flat(foot.lock_position);
            foot.turn_about(up, 0.0, to, Some((o_from, o_to)), share);
            let after = point(&foot, o_to);
            assert!(
                (after - before).length() < 1e-5,
                "{share} {rise}: {before} -> {after}"
            );
            assert_eq!(foot.lock_heading, to);
            // The rest of the sole turned about that point: its heel moved along the chord of
            // the turn, `share` of the foot's reach over the ground from the pivot.
            let heel_after = flat(foot.lock_position);
            let moved = (heel_after - heel_before).length();
            let reach = (0.15f32 * 0.15 - 0.06 * 0.06).sqrt();
            let expected = share * 2.0 * reach * (0.5f32 * (to - from)).abs().sin();
            assert!(
                (moved - expected).abs() < 1e-5,
                "{share} {rise}: {moved} vs {expected}"
            );
        }
    }

    #[test]
    fn a_free_ball_under_the_floor_lifts_a_bent_leg_more_than_a_straight_one() {
        let up = Vec3::Y;
        // A 0.9 m leg under a hip at 1 m, its foot 15 cm long pointed 60° down.
        let o = Vec3::new(0.15 * 0.5, -0.15 * 0.866, 0.0);
        let leg = |bend: f32| {
            let half = 0.5 * bend.to_radians();
            let hip = Vec3::new(0.0, 1.0, 0.0);
            let knee = hip + Vec3::new(0.45 * half.sin(), -0.45 * half.cos(), 0.0);
            let ankle = knee + Vec3::new(-0.45 * half.sin(), -0.45 * half.cos(), 0.0);
            [hip, knee, ankle, Vec3::X]
        };
        let need = 0.02;
        let bent = leg(60.0);
        let straight = leg(4.0);
        let lift_bent = split_lift(bent, bent[2], o, up, need);
        let lift_straight = split_lift(straight, straight[2], o, up, need);
        // Both within the need, the bent leg taking more of it than the nearly straight one.
        for l in [lift_bent, lift_straight] {
            assert!((0.0..=need + 1e-6).contains(&l), "{l}");
        }
        assert!(lift_bent > 0.5 * need, "{lift_bent}");
        assert!(
            lift_straight < 0.5 * lift_bent,
            "{lift_straight} vs {lift_bent}"
        );
        // Nothing under the floor, nothing lifted.
        assert!(split_lift(bent, bent[2], o, up, 0.0).abs() < 1e-6);
        // A foot pointed 80° down (steeper than a pitch may go up to): pitching it up turns it
        // as far as its own pitch changes, so the bent leg still takes most of the need.
        let steep = Vec3::new(0.15 * 0.174, -0.15 * 0.985, 0.0);
        let lift_steep = split_lift(bent, bent[2], steep, up, need);
        assert!(lift_steep > 0.5 * need, "{lift_steep}");
    }

    #[test]
    fn a_lifted_free_foot_moves_over_the_ground_where_its_leg_turns_less() {
        let up = Vec3::Y;
        // A short thigh (20 cm) over a long shin (40 cm), reaching forward as it comes down:
        // the thigh 25° ahead of straight down, the shin 5° ahead, the knee bending forward.
        let dir = |deg: f32| Vec3::new(deg.to_radians().sin(), -deg.to_radians().cos(), 0.0);
        let hip = Vec3::new(0.0, 1.0, 0.0);
        let knee = hip + dir(25.0) * 0.2;
        let ankle = knee + dir(5.0) * 0.4;
        let pole = bend_of(hip, knee, ankle);
        let leg = [hip, knee, ankle, pole];
        let turns = |goal: Vec3| {
            let s = solve_bounded(hip, knee, ankle, goal, pole);
            let thigh = (knee - hip).angle_between(s.knee - hip).to_degrees();
            let shin = (ankle - knee).angle_between(s.ankle - s.knee).to_degrees();
            (thigh, shin, s.ankle)
        };
        // Lifted 3 cm onto its floor.
        let lifted = ankle + up * 0.03;
        let aside = lift_aside(leg, lifted, up, 0.2, 0.6);
        // Over the ground only, within the reach, and along the leg's own plane.
        assert!(
            aside.dot(up).abs() < 1e-6 && aside.z.abs() < 1e-6,
            "{aside}"
        );
        assert!(
            aside.length() > 0.005 && aside.length() <= 0.2 + 1e-6,
            "{aside}"
        );
        let (t0, s0, _) = turns(lifted);
        let (t1, s1, reached) = turns(lifted + aside);
        // Still lifted as far (the goal reached), for less turn: the thigh most.
        assert!((reached - (lifted + aside)).length() < 1e-4, "{reached}");
        assert!(
            t1 * t1 + s1 * s1 < t0 * t0 + s0 * s0,
            "{t1}/{s1} vs {t0}/{s0}"
        );
        assert!(t1 < t0 - 2.0, "thigh {t1} vs {t0}");
        // Nothing lifted, nothing moved; no reach, no move.
        assert_eq!(lift_aside(leg, ankle, up, 0.2, 0.6), Vec3::ZERO);
        assert_eq!(lift_aside(leg, lifted, up, 0.0, 0.6), Vec3::ZERO);
    }

    #[test]
    fn a_short_upper_bone_is_not_folded_over_to_lift_the_foot() {
        // A 6 cm upper bone above a 37 cm lower one (a hip joint at the pelvis centre), the
        // foot to come up 10 cm.
        let (hip, knee, ankle) = (
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.94, 0.01),
            Vec3::new(0.0, 0.57, 0.0),
        );
        let goal = ankle + Vec3::Y * 0.1;
        let pole = Vec3::Z;
        let turn = |s: &TwoBoneSolution| {
            let upper = (knee - hip).angle_between(s.knee - hip);
            let lower = (ankle - knee).angle_between(s.ankle - s.knee);
            upper.max(lower)
        };
        let free = solve_two_bone(hip, knee, ankle, goal, pole);
        assert!(
            turn(&free) > MAX_BONE_TURN,
            "the unbounded IK folds: {}",
            turn(&free)
        );
        let bounded = solve_bounded(hip, knee, ankle, goal, pole);
        assert!(turn(&bounded) <= MAX_BONE_TURN + 1e-4, "{}", turn(&bounded));
        assert!(
            bounded.ankle.y > ankle.y + 0.005,
            "the foot came up {}",
            bounded.ankle.y - ankle.y
        );
        // An ordinary adjustment is left alone.
        let small = ankle + Vec3::new(0.0, 0.01, 0.02);
        let plain = solve_two_bone(hip, Vec3::new(0.0, 0.8, 0.02), ankle, small, pole);
        let same = solve_bounded(hip, Vec3::new(0.0, 0.8, 0.02), ankle, small, pole);
        assert!((plain.ankle - same.ankle).length() < 1e-6);
    }
}
