//! The fit to the standing posture: each foot's standing pitch and height, and the hips' height,
//! from the animation's typical stance (offline: medians over the clip, [`FootLock::fit_to_standing`];
//! live: the feet's pitch the median of the stances held so far, the hips' height a running
//! average), and what the rig's rest tells of them.

use super::*;

/// How long (seconds) the live fit to the standing posture takes to follow a new stance gap
/// (the time constant of its running average).
pub(super) const FIT_LEARN_SECS: f32 = 1.0;

/// Largest pitch (radians, ~40°) the live fit gives a foot: past that the gap is no foot
/// built differently but a pose the detector took for a stance.
pub(super) const MAX_FIT_PITCH: f32 = 0.7;

/// A leg's foot as it stands in the character's aligned rest: its clearances above `lowest`,
/// its length and standing pitch, and the local axes the lock turns it by; not yet locked.
/// `source` is the watched source leg it follows, if any. `own`: the character's own rest
/// (world transforms), where that rest is how it stands: the foot's side axis is then its
/// own sole's ([`own_side_axis`]).
pub(super) fn standing_foot(
    leg: &Leg,
    source: Option<usize>,
    aligned: &[WorldTransform],
    own: Option<&[WorldTransform]>,
    target: &Analysis,
    up: Vec3,
    lowest: f32,
) -> Foot {
    let height = |b: BoneId| target.positions[b.index()].dot(target.up);
    let w = |b: BoneId| aligned[b.index()];
    let ankle = w(leg.foot).translation;
    let ahead = leg
        .toes
        .map(|t| w(t).translation - ankle)
        .unwrap_or(Vec3::ZERO);
    let flat = ahead - up * ahead.dot(up);
    let heading_dir = flat
        .try_normalize()
        .unwrap_or_else(|| up.any_orthonormal_vector());
    let knee = w(leg.lower).translation;
    let hip = w(leg.upper).translation;
    let bend = bend_of(hip, knee, ankle);
    // Knees bend the way the toes point; a quadruped's elbows the other way.
    let toward = match leg.kind {
        crate::footplant::rig::LegKind::Hind => heading_dir,
        crate::footplant::rig::LegKind::Front => -heading_dir,
    };
    let pole = if bend.length() > 0.02 * leg.length {
        bend
    } else {
        toward
    };
    Foot {
        heel_clearance: height(leg.foot) - lowest,
        ball_clearance: leg.toes.map(|t| height(t) - lowest).unwrap_or(0.0),
        foot_length: ahead.length(),
        standing_pitch: leg.toes.map_or(0.0, |t| {
            let o = target.positions[t.index()] - target.positions[leg.foot.index()];
            (o.dot(target.up) / o.length().max(1e-6))
                .clamp(-1.0, 1.0)
                .asin()
        }),
        side_local: own
            .and_then(|rest| own_side_axis(leg, rest, target.up))
            .unwrap_or_else(|| w(leg.foot).rotation.inverse() * heading_dir.cross(up)),
        // Towards the ball: a pinned ball keeps its place however the foot twists.
        heading_local: w(leg.foot).rotation.inverse()
            * ahead.try_normalize().unwrap_or(heading_dir),
        pole_local: (w(leg.upper).rotation.inverse() * pole).normalize_or_zero(),
        carried: leg.carried.then(|| {
            let shin = w(leg.lower);
            shin.rotation.inverse() * (ankle - shin.translation)
        }),
        ..Foot::unlocked_at(*leg, source, ankle)
    }
}

/// The axis across a foot's sole as the character stands in its own rest (`rest`, world
/// transforms, `up` its up), fixed in the foot bone's frame: ahead (ankle to ball) over the
/// ground, across up. What the fit to the standing posture pitches the foot about
/// ([`FootLock::apply_fit`]): the aligned rest poses the foot as the source's rest stands, and
/// the turn that takes it there may roll it about its length as well, so an axis read off it
/// is tilted out of the sole, and pitching about it swung the foot's heading (the CMU walk
/// onto X Bot, fitted 20-26° down: the foot 9.2° mean off the performer's on its own standing
/// foot, most of it heading; 4.2° about this axis). `None` without a ball or for a foot
/// pointing straight down.
pub(super) fn own_side_axis(leg: &Leg, rest: &[WorldTransform], up: Vec3) -> Option<Vec3> {
    let foot = rest[leg.foot.index()];
    let ahead = rest[leg.toes?.index()].translation - foot.translation;
    let flat = (ahead - up * ahead.dot(up)).try_normalize()?;
    Some(foot.rotation.inverse() * flat.cross(up))
}

/// Whether a posture's feet stand on its own ground (height 0 along its own up): its lowest
/// foot joint within a quarter of a leg of it, as the retarget reads a reference posture's
/// floor. A rest floating at the origin (CMU's: hips there, feet a leg below) does not.
pub(super) fn rest_on_own_ground(legs: &[Leg], posture: &Analysis) -> bool {
    let height = |b: BoneId| posture.positions[b.index()].dot(posture.up);
    let lowest = (legs.iter())
        .flat_map(|l| [Some(l.foot), l.toes])
        .flatten()
        .map(height)
        .fold(f32::INFINITY, f32::min);
    let leg = legs.iter().map(|l| l.length).fold(f32::INFINITY, f32::min);
    lowest.abs() <= 0.25 * leg
}

/// How high above its ground source leg `leg`'s ball stands while its foot stands flat (heel
/// and ball holding): the median over those frames of `plants`, 0 where there are none.
pub(super) fn flat_ball_height(plants: &PlantTrack, leg: usize) -> f32 {
    let mut v: Vec<f32> = (0..plants.num_frames())
        .filter(|&f| plants.contacts(f).get(leg).copied().flatten() == Some(Contact::Flat))
        .filter_map(|f| plants.ball_lifts(f).get(leg).copied())
        .collect();
    v.sort_by(f32::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Bins of [`FitMedian`]'s histogram: half a degree each over ±[`MAX_FIT_PITCH`].
const FIT_BINS: usize = 160;

/// Live: the median of a foot's stance pitch gaps seen so far (each frame weighted by its
/// time), in a fixed histogram: nothing allocated per frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct FitMedian {
    weights: [f32; FIT_BINS],
    total: f32,
}

impl Default for FitMedian {
    fn default() -> Self {
        FitMedian {
            weights: [0.0; FIT_BINS],
            total: 0.0,
        }
    }
}

impl FitMedian {
    const WIDTH: f32 = 2.0 * MAX_FIT_PITCH / FIT_BINS as f32;

    /// Counts `gap` (radians, within ±[`MAX_FIT_PITCH`]) with weight `w`.
    pub(super) fn add(&mut self, gap: f32, w: f32) {
        let t = (gap + MAX_FIT_PITCH) / Self::WIDTH;
        if !(t.is_finite() && w > 0.0) {
            return;
        }
        let b = (t.max(0.0) as usize).min(FIT_BINS - 1);
        self.weights[b] += w;
        self.total += w;
    }

    /// The median of what was counted (linear within its bin), `None` before anything was.
    pub(super) fn median(&self) -> Option<f32> {
        let half = 0.5 * self.total;
        let mut below = 0.0;
        for (b, &w) in self.weights.iter().enumerate() {
            if w > 0.0 && below + w >= half {
                let t = b as f32 + (half - below) / w;
                return Some(-MAX_FIT_PITCH + t * Self::WIDTH);
            }
            below += w;
        }
        None
    }
}

impl Foot {
    /// Live: counts this held frame's stance pitch gap (`gap`, the posture's pitch less the
    /// animation's), `dt` long, into the foot's pitch fit, which is the median of every such
    /// frame seen, as offline's [`FootLock::fit_to_standing`] takes the whole clip's median: a
    /// rig's foot is built one way for the whole performance, while the performer's stance
    /// pitch wanders about its own (Xia's walk: a planted foot 12-24° down over one stance
    /// as its heel rises within the detector's bound). A foot's first stance sets it at once
    /// (from zero a running average took a second or two, the character's feet tipped by the
    /// whole gap meanwhile: live, the CMU walk onto X Bot, the foot 11° and 9° off in its first
    /// two seconds). Frames on the ball alone (a toe-off: the roll's pitch, not the stance's)
    /// are left out by the source's own contacts. Left out before by the lock's own roll of
    /// the fitted foot, the fit read only the frames its first value stood flat: Xia's walk
    /// onto X Bot kept the fit of its first stance frames, the foot 7.5° off the performer's
    /// for the whole clip (8.8/10.9° mean/p95; offline 1.8/8.0). A planted foot stands at its
    /// pinned pitch whatever the fit; the one it pitches is the foot it learns on.
    pub(super) fn learn_pitch_fit(&mut self, gap: f32, dt: f32) {
        if self.contact == Some(Contact::Ball) {
            return;
        }
        self.fit_secs += dt;
        self.fit.add(gap.clamp(-MAX_FIT_PITCH, MAX_FIT_PITCH), dt);
        if let Some(m) = self.fit.median() {
            self.pitch_fix = m;
        }
    }
}

impl FootLock {
    /// Offline: fits the animation to the character's standing posture before locking. The
    /// retarget gives each foot the source's foot direction, so on a rig whose foot is built
    /// differently (its toe joint higher or lower against the ankle) a planted foot is pitched
    /// off the posture's flat foot, and the whole character may stand high or low. The lock
    /// then stands each planted foot flat at its posture's heights, and every landing and
    /// lift-off blends across that gap. Here the typical gap is measured on the frames whose
    /// source foot is planted (medians) and taken out of every frame: each foot pitched about
    /// its ankle by its own angle, the hips moved by the feet's mean height error. A target
    /// whose rest does not stand on a floor (a CMU-style rest floating at the origin), or whose
    /// posture is a frame of its own motion (a folded rest), has no standing posture to fit to:
    /// its standing heights are taken from the animation instead.
    /// `animated` is the clip retargeted without the lock, `plants` its source's plants (from
    /// [`super::detect_clip`]). Allocates (height lists).
    pub fn fit_to_standing(&mut self, animated: &[Pose], plants: &PlantTrack) {
        let mut worlds = vec![WorldTransform::IDENTITY; self.target.num_bones()];
        let mut seen: Vec<Vec<Stance>> = vec![Vec::new(); self.feet.len()];
        for (frame, pose) in animated.iter().enumerate() {
            if pose.check(&self.target).is_err() {
                continue;
            }
            forward_kinematics(&self.target, pose, &mut worlds);
            for (foot, h) in self.feet.iter().zip(&mut seen) {
                let Some(s) = foot.source.filter(|&s| plants.is_planted(frame, s)) else {
                    continue;
                };
                let at = |v: &[f32]| v.get(s).copied().unwrap_or(0.0);
                let rise = at(plants.heel_lifts(frame)) - at(plants.lifts(frame)).max(0.0);
                let rise = self.lift_scale * rise.max(0.0);
                h.push(Stance {
                    heel_rise: foot.ball().map_or(rise.min(foot.heel_reach), |_| rise),
                    ..self.stance_of(foot, &worlds)
                });
            }
        }
        for foot in &mut self.feet {
            foot.ball_standing = foot.source.map(|s| flat_ball_height(plants, s));
        }
        let median = |h: &[Stance], key: fn(&Stance) -> f32| {
            let mut v: Vec<f32> = h.iter().map(key).collect();
            v.sort_by(f32::total_cmp);
            v.get(v.len() / 2).copied()
        };
        let (mut rise_sum, mut n) = (0.0, 0);
        for (foot, h) in self.feet.iter_mut().zip(&seen) {
            let Some(pitch) = median(h, |s| s.pitch) else {
                continue;
            };
            // A rest that does not stand (hips at the origin, feet hanging below) says nothing
            // about how the rig stands: the animation is the best guess (its typical pitch).
            let (standing, fix) = if self.posture_stands || self.rest_feet_stand {
                (foot.standing_pitch, foot.standing_pitch - pitch)
            } else {
                (pitch, 0.0)
            };
            // Where the heel stands on each frame as the lock rolls the foot ([`Foot::roll`]):
            // a frame on its ball (pitched lower than standing, the source's heel up) has its
            // ankle raised by that.
            let heels: Vec<Stance> = (h.iter())
                .map(|s| Stance {
                    ankle: s.ankle - s.rolled(foot.ball(), standing, fix),
                    ..*s
                })
                .collect();
            let Some(heel) = median(&heels, |s| s.ankle) else {
                continue;
            };
            if self.posture_stands {
                foot.pitch_fix = fix;
                rise_sum += foot.heel_clearance - heel;
                n += 1;
            } else {
                // Standing heights from the animation, the pitch from the rest where its feet
                // stand on its own ground.
                foot.pitch_fix = fix;
                foot.standing_pitch = standing;
                foot.heel_clearance = heel;
                foot.ball_clearance = heel + foot.foot_length * standing.sin();
                foot.learns_heights = false;
            }
        }
        self.root_fix = if n > 0 { rise_sum / n as f32 } else { 0.0 };
    }

    /// A foot's ankle height above the floor and its pitch in `worlds`.
    pub(super) fn stance_of(&self, foot: &Foot, worlds: &[WorldTransform]) -> Stance {
        let ankle = worlds[foot.leg.foot.index()].translation;
        let height = |p: Vec3| p.dot(self.up) - self.floor;
        let Some(toes) = foot.leg.toes else {
            let h = height(ankle);
            return Stance {
                ankle: h,
                heel_rise: 0.0,
                pitch: 0.0,
            };
        };
        let ball = worlds[toes.index()].translation;
        let o = ball - ankle;
        Stance {
            ankle: height(ankle),
            heel_rise: 0.0,
            pitch: (o.dot(self.up) / o.length().max(1e-6))
                .clamp(-1.0, 1.0)
                .asin(),
        }
    }

    /// Live: moves the fit of [`FootLock::fit_to_standing`] towards this frame's stance gap
    /// (`worlds` hold the animation), learnt on the frames with a foot held by a lock since the
    /// frame before (a landing foot is still on its way down): each foot's pitch the median of
    /// them ([`Foot::learn_pitch_fit`]), the hips' height an average over the last
    /// [`FIT_LEARN_SECS`] or so. Slow enough that the correction never shows as a movement of its own. As
    /// offline, a rest standing on its own ground along its own up gives the feet's pitch even
    /// where the retarget places no floor for it (MakeHuman's: its rest along Z, its motion
    /// along Y); the hips are moved onto the standing heights only where the posture stands.
    /// Live or not, a foot whose floor the mapping does not know and no clip gave heights to
    /// ([`Foot::learns_heights`]) learns its standing heights the same way, off the animation:
    /// pinned at the mapping's floor, LaFAN1's walk onto Casual had its pins 78-101 cm over
    /// the animation's ankles, the thighs 45° mean off the performer's.
    pub(super) fn learn_fit(&mut self, planted: &[bool; MAX_FEET], dt: f32, live: bool) {
        let pitch = live && (self.posture_stands || self.rest_feet_stand);
        if !(pitch || self.feet.iter().any(|f| f.learns_heights)) || dt <= 0.0 {
            return;
        }
        let k = 1.0 - (-dt / FIT_LEARN_SECS).exp();
        let (mut rise, mut n) = (0.0, 0);
        for i in 0..self.feet.len() {
            let foot = &self.feet[i];
            // A foot learning its heights is pinned only once it knows them: its first
            // planted frame is read before any pin.
            let held = foot.locked || !foot.stands_known();
            if !(held && foot.source.is_some_and(|s| planted[s])) {
                // A foot that has stood and stands no more is past its stance.
                self.feet[i].end_stance();
                continue;
            }
            if !(pitch || foot.learns_heights) {
                continue;
            }
            let stance = Stance {
                heel_rise: foot.heel_rise,
                ..self.stance_of(foot, &self.worlds)
            };
            let (gap, clearance) = (foot.standing_pitch - stance.pitch, foot.heel_clearance);
            // A foot rolling onto its ball (a toe-off) stands its heel lower than its ankle,
            // and its pitch is the roll's, not the stance's: learnt from flat frames only.
            let rolled = stance.rolled(foot.ball(), foot.standing_pitch, foot.pitch_fix);
            let rest_pitch = self.posture_stands || self.rest_feet_stand;
            let foot = &mut self.feet[i];
            if pitch {
                foot.learn_pitch_fit(gap, dt);
            } else if rolled <= 0.0 {
                foot.fit_secs += dt;
                if foot.learns_heights && !rest_pitch {
                    // No rest to stand it as: the animation's own pitch, as offline.
                    foot.learn_standing_pitch(stance.pitch, dt);
                }
            }
            if foot.learns_heights {
                // Where the heel stands as the lock rolls the foot, from its first stance at
                // once (as the pitch): as offline, off the animation, not the unknown floor.
                // Over that stance only, then held: the performer's floor does not move, and
                // a pin moved by what later stances add (the mean of every stance seen) stood
                // the character's planted feet higher or lower on each stance than on the
                // first (live, the CMU 131_02 walk onto the CMU 131_01 rig: one heel's pin 8.9
                // cm up after its first stance, 10.0 by its last; the pymo Meredith walk onto
                // the CMU 131_01 rig: planted feet 3.09 cm off the performer's, 0.96 held);
                // learnt again from the later stances where the first was none of theirs
                // ([`Foot::end_stance`]).
                foot.take_stance(stance.ankle - rolled, dt);
            }
            if foot.learns_heights {
                // The ball's height follows the pitch, learnt on.
                foot.ball_clearance =
                    foot.heel_clearance + foot.foot_length * foot.standing_pitch.sin();
            }
            rise += clearance - (stance.ankle - rolled);
            n += 1;
        }
        if pitch {
            self.share_pitch_fit(dt);
        }
        // A rest standing along its own up only (no floor placed for it) gives the feet's
        // pitch alone: its standing heights are not this world's.
        if n > 0 && pitch && self.posture_stands {
            let limit = self.settings.max_drop_ratio * self.feet[0].leg.length;
            let wanted = clamp_safe(rise / n as f32, -limit, limit);
            self.root_fix += k * (wanted - self.root_fix);
        }
    }

    /// Live: a foot that has not stood flat yet takes the pitch fit its fellow feet of its
    /// kind have learnt (their mean), over the blends' half-life (`dt` since the last frame):
    /// one character's feet are built alike, as the performer's are. Left at none, a foot's
    /// first plant pitched it from the performer's pitch to its own over a blend's time (the
    /// CMU walk onto X Bot: the second foot's first plant stood its toes 5 cm up); taken at
    /// once, the swinging foot kicked (the built-in mannequin under the CMU walk, live: 3.7
    /// cm/frame² against 1.6 unlocked).
    fn share_pitch_fit(&mut self, dt: f32) {
        let halflife = 0.5 * self.settings.blend_secs;
        let follow = 1.0 - (-dt * std::f32::consts::LN_2 / halflife).exp();
        for i in 0..self.feet.len() {
            if self.feet[i].fit_secs > 0.0 || self.feet[i].source.is_none() {
                continue;
            }
            let kind = self.feet[i].leg.kind;
            let (mut sum, mut n) = (0.0, 0);
            for f in &self.feet {
                if f.fit_secs > 0.0 && f.leg.kind == kind {
                    sum += f.pitch_fix;
                    n += 1;
                }
            }
            if n > 0 {
                let f = &mut self.feet[i];
                f.pitch_fix += follow * (sum / n as f32 - f.pitch_fix);
            }
        }
    }

    /// Applies [`FootLock::fit_to_standing`]'s corrections to `out`; `worlds` is its FK and is
    /// brought up to date. Returns whether anything moved.
    pub(super) fn apply_fit(&mut self, out: &mut Pose) -> bool {
        let moved = self.root_fix != 0.0 || self.feet.iter().any(|f| f.pitch_fix != 0.0);
        if !moved {
            return false;
        }
        if let Some(root) = self.root {
            let parent = match self.target.parent(root) {
                Some(p) => self.worlds[p.index()].rotation,
                None => Quat::IDENTITY,
            };
            out.translations[root.index()] += parent.inverse() * (self.up * self.root_fix);
        }
        for foot in &self.feet {
            if foot.pitch_fix == 0.0 {
                continue;
            }
            // About the foot's own side axis (not one taken from its heading, which swings
            // about as the foot points down at a toe-off): ahead × up, so a positive angle
            // turns the ball up.
            let w = self.worlds[foot.leg.foot.index()].rotation;
            let turned = Quat::from_axis_angle(w * foot.side_local, foot.pitch_fix) * w;
            let parent = match self.target.parent(foot.leg.foot) {
                Some(p) => self.worlds[p.index()].rotation,
                None => Quat::IDENTITY,
            };
            out.rotations[foot.leg.foot.index()] = (parent.inverse() * turned).normalize();
        }
        self.fk(out);
        true
    }
}
