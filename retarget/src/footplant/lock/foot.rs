//! One target foot's lock state ([`Foot`]): where it is pinned, how it rolls on its ball or heel
//! and turns about the joint it stands on, the blends at a switch; a foot's stance on a frame
//! ([`Stance`]) and its per-frame goal ([`Goal`]).

use super::*;

/// A leg whose knee stands less than this many leg lengths off its hip-to-ankle line counts as
/// straight: its bend side is the one remembered ([`Foot::pole`]).
pub(super) const STRAIGHT_BEND_RATIO: f32 = 0.01;

/// Live, how fast a pin on its ball may rise towards the animation's ankle as its lift-off
/// nears, in leg lengths a second (when the animation lifts the ankle no faster;
/// [`Foot::raise_limit`]). In process, live (152 pairs, thigh+shin / floor / every bound):
/// 0.65 gave 136 / 96 / 81, 1 136 / 99 / 84 (132 / 97 / 81 before).
pub(super) const RAISE_LEGS_PER_SEC: f32 = 1.0;

/// The knee's offset from the hip-to-ankle line: the side the leg bends to (zero when straight).
pub(super) fn bend_of(hip: Vec3, knee: Vec3, ankle: Vec3) -> Vec3 {
    let line = (ankle - hip).normalize_or_zero();
    (knee - hip) - line * (knee - hip).dot(line)
}

/// Pitches `g`'s foot about the ankle so that its ball is `wanted` above the ankle along `up`
/// (at most [`MAX_BALL_RISE`] of the foot's length either way); returns the height reached.
pub(super) fn pitch_ball(g: &mut Goal, up: Vec3, wanted: f32) -> f32 {
    let Some(o) = g.ball_offset else { return 0.0 };
    let (len, rise) = (o.length(), o.dot(up));
    // A foot already pitched past the limit (pointing down at a toe-off) is not snapped back
    // to it: the limit bounds only how far this pitch goes.
    let limit = len * MAX_BALL_RISE;
    let wanted = clamp_safe(wanted, (-limit).min(rise), limit.max(rise));
    let flat = (o - up * rise)
        .try_normalize()
        .unwrap_or(up.any_orthonormal_vector());
    let pitched = flat * (len * len - wanted * wanted).max(0.0).sqrt() + up * wanted;
    let (Some(from), Some(to)) = (o.try_normalize(), pitched.try_normalize()) else {
        return rise;
    };
    g.rotation = (Quat::from_rotation_arc(from, to) * g.rotation).normalize();
    g.ball_offset = Some(pitched);
    wanted
}

/// One target foot and its lock state.
#[derive(Debug, Clone, Copy)]
pub(super) struct Foot {
    pub(super) leg: Leg,
    /// The source leg (index into the detector's legs) whose plants drive this foot.
    pub(super) source: Option<usize>,
    /// Standing heights of heel and ball above the floor (the mapping floor's joint; negative
    /// for a ball below an ankle the floor is measured at).
    pub(super) heel_clearance: f32,
    pub(super) ball_clearance: f32,
    /// Ankle to ball (0 without a ball).
    pub(super) foot_length: f32,
    /// The posture's foot pitch (radians, ball above the ankle positive) and the pitch added
    /// to the animation's ([`FootLock::fit_to_standing`]).
    pub(super) standing_pitch: f32,
    pub(super) pitch_fix: f32,
    /// Live: how long (seconds) this foot has stood flat under a lock, what its `pitch_fix`
    /// has been learnt from ([`FootLock::learn_fit`]).
    pub(super) fit_secs: f32,
    /// Live: the stance pitch gaps seen, whose median is `pitch_fix` ([`FootLock::learn_fit`]).
    pub(super) fit: FitMedian,
    /// The character's posture does not stand on its floor (the mapping knows no floor for
    /// it, it floats, or it is a frame of its own motion), and no clip was read for the foot's
    /// standing heights: it learns them from its flat stances
    /// ([`FootLock::learn_fit`]), and is not pulled towards that floor before it has stood.
    pub(super) learns_heights: bool,
    /// How long (seconds) such a foot has stood since: what its heights are learnt from.
    pub(super) stand_secs: f32,
    /// Such a foot's first stance is over: its heights, learnt there, are held from now on
    /// ([`FootLock::learn_fit`]), unless the later stances tell it apart ([`Foot::end_stance`]).
    pub(super) heights_held: bool,
    /// The heel's standing height over the stance standing now, its mean over the first
    /// stance, and the means of the stances after it ([`Foot::end_stance`]); whether their
    /// mean has replaced the first's.
    pub(super) stance_heel: Moments,
    pub(super) first_heel: f32,
    pub(super) later_heel: Moments,
    pub(super) relearnt: bool,
    /// The mean of the heel's standing heights seen so far, and of their squares (their
    /// spread), [`Foot::learn_height`].
    pub(super) learnt_mean: f32,
    pub(super) learnt_sq: f32,
    /// Where the mapping places the character's floor and its posture is its own (a rest
    /// that floats, or stands along an up of its own): the heel's standing height its rest
    /// gives, which the motion may confirm ([`Foot::learn_height`]).
    pub(super) rest_heel: Option<f32>,
    /// The foot's left-to-right axis, fixed in the foot bone's frame: what it pitches about.
    pub(super) side_local: Vec3,
    /// A direction fixed in the foot bone's frame whose way over the ground is the foot's
    /// heading: towards the ball, or (without one) ahead at rest.
    pub(super) heading_local: Vec3,
    /// The knee's side of the hip–ankle line, in the upper bone's frame (kept for straight
    /// legs, where the animation does not show it).
    pub(super) pole_local: Vec3,
    pub(super) locked: bool,
    /// How far above its standing height the source holds its foot this frame (its lowest
    /// contact above its ground, scaled to the target): a pinned foot follows it.
    pub(super) lift: f32,
    /// When the source's heel is known: how far above its standing height the ankle is brought
    /// ahead of a plant ([`FootLock::pin_height`]), the foot's lift plus how much higher the
    /// source's heel stands than its lowest contact (a foot landing toes first).
    pub(super) heel_lift: Option<f32>,
    /// Offline, once [`FootLock::fit_to_standing`] has read it: how high above its ground the
    /// source's ball stands while the source's foot stands flat (source units, the median
    /// over those frames). A ball joint sits above the sole, and rolling over it at a toe-off
    /// takes it lower than standing does: the ground the detector reads is that low point
    /// (LaFAN1's stands 2 cm above it, the CMU 31-joint rig's 4-5 cm, scaled to X Bot).
    pub(super) ball_standing: Option<f32>,
    /// How far the source's ball stands above that this frame (scaled to the target, never
    /// below 0; `None` where not known): how far a pinned or landing foot's ball may stay
    /// above its standing height ([`FootLock::flatten`]).
    pub(super) ball_lift: Option<f32>,
    /// How much higher the source's heel stands above its ground than its lowest contact
    /// (scaled to the target; offline, 0 where not known): how far the foot may roll onto its
    /// ball ([`Foot::roll`]); a foot without one, by how much its ankle rises with the heel.
    pub(super) heel_rise: f32,
    /// How far (0 to 1) the foot rolls onto its ball by its own geometry rather than only as
    /// far as the source's heel rises ([`Foot::roll`]): 1 while only the source's ball holds
    /// (its heel up: a toe-off, a stand on the toes), followed over the blends' half-life.
    pub(super) on_ball: f32,
    /// A foot without a ball (its ankle the lowest joint, the toes not rigged): how far its
    /// ankle may rise with the source's heel, the source's foot length scaled. Its sole still
    /// rolls over a ball, as the performer's does, that the skeleton does not show: pinned on
    /// the floor instead, the ankle holds the leg down while the performer's heel rises, and
    /// the hips come down onto it, bending the other leg.
    pub(super) heel_reach: f32,
    /// How far the unpinned foot is brought to its pin's height ahead of a plant
    /// ([`landing_weight`], [`LiveLanding`]), and how far its ball to its standing height.
    pub(super) landing: f32,
    pub(super) landing_flat: f32,
    /// `landing` on the frame before (what a foot landing this frame still counts for in the
    /// body's height, [`FootLock::body_height`]).
    pub(super) landing_before: f32,
    pub(super) lock_position: Vec3,
    pub(super) lock_heading: f32,
    /// Where along its sole, heel (0) to ball (1), a pinned foot turns with the animation this
    /// frame ([`Foot::pivot_of`], [`FootLock::turn_pins`]); `None` where the source's contacts
    /// are not known (plants given as flags alone) or none of them holds: the heading is then
    /// held, dragged past [`PIVOT_RAD`].
    pub(super) pivot: Option<f32>,
    /// Which of the source foot's contacts hold this frame (`None` where not known).
    pub(super) contact: Option<Contact>,
    /// How far this frame's turn moved the pin over the ground (the root takes it up).
    pub(super) pin_moved: Vec3,
    /// The shown ankle minus where it should go (the lock, or the animated foot), decaying.
    pub(super) position_offset: Decay<Vec3>,
    pub(super) heading_offset: Decay<f32>,
    /// How far the ball is pitched up (+) or down about the ankle to stand flat, metres along
    /// up: what is wanted minus what was shown at the last switch, decaying; and what was shown.
    pub(super) flat_offset: Decay<f32>,
    pub(super) shown_flat: f32,
    /// How far (radians) the foot was shown pitched toes up past standing last frame.
    pub(super) toes_up: f32,
    /// Last frame: where the ankle was shown and the animated ankle, for velocities.
    pub(super) shown_position: Vec3,
    pub(super) shown_velocity: Vec3,
    pub(super) shown_heading: f32,
    pub(super) shown_heading_rate: f32,
    pub(super) animated_position: Vec3,
    pub(super) animated_heading: f32,
    /// The foot has been seen (velocities are known).
    pub(super) seen: bool,
    /// Last frame's animated ankle before the root's move onto the standing feet (the foot's
    /// slide over the ground, [`FootLock::carry_root`]).
    pub(super) raw_ankle: Vec3,
    /// This frame's animated ankle along up (after the fit; offline before the root is carried
    /// onto the standing feet, live after): where the retargeted foot stands.
    pub(super) animated_up: f32,
    /// How near the source foot's lift-off is (0 to 1, [`release_weight`]).
    pub(super) release: f32,
    /// How far this frame's pin was raised towards the animation's ankle
    /// ([`Foot::raise_to_animation`]): how far its ball may stay above its standing height.
    pub(super) raised: f32,
    /// The most this frame's raise may be ([`Foot::raise_limit`]; unbounded offline).
    pub(super) raise_most: f32,
    /// Last frame's animated ankle along up, before the root's move onto the standing feet
    /// (how fast the animation lifts it, [`Foot::raise_limit`]).
    pub(super) animated_up_before: Option<f32>,
    /// A foot carried at its shin's end from beside the body ([`Leg::carried`]): where it
    /// sits in the lower bone's frame, so it goes wherever the leg puts the shin.
    pub(super) carried: Option<Vec3>,
    /// Offline, a swinging foot's move over the ground where its leg turns least as the floor
    /// lifts it ([`lift_aside`]), following the move wanted with the blends' spring: as
    /// [`FootLock::step_aside`] shows it, less the move wanted (0 while none is).
    pub(super) aside: Decay<Vec3>,
    /// The move wanted last frame.
    pub(super) aside_wanted: Vec3,
}

impl Foot {
    /// The side the foot's leg bends to for the IK: the animation's own bend (`hip`, `knee`,
    /// `ankle`), or the one remembered in the thigh's frame (`upper`, its world rotation)
    /// while the leg is nearly straight.
    pub(super) fn pole(&self, [hip, knee, ankle]: [Vec3; 3], upper: Quat) -> Vec3 {
        let bend = bend_of(hip, knee, ankle);
        if bend.length() > STRAIGHT_BEND_RATIO * self.leg.length {
            bend
        } else {
            upper * self.pole_local
        }
    }

    /// Whether the foot's standing heights above the lock's floor are known: given by the
    /// mapping or the clip, or learnt from a flat stance ([`Foot::learns_heights`]).
    pub(super) fn stands_known(&self) -> bool {
        !self.learns_heights || self.stand_secs > 0.0
    }

    /// The foot's heading (radians about `up`) with its bone at world `rotation`: the way to
    /// its ball over the ground (`heading_local`'s) as far as that is defined
    /// ([`level_weight`]), for the rest the way its side axis gives (ahead of it, across up).
    /// What a pin turns with ([`FootLock::turn_pins`]), what it is shown turned by, and the
    /// way its rolled contact lies ([`FootLock::carry_root`]). A foot pointing straight down
    /// at a toe-off flips the way to its ball from one sample to the next while its side axis
    /// stays level: turned to that way, the pin swung about its ball and the carried contact
    /// jumped (the pymo Meredith walk onto X Bot, live: 17.7 cm while the ball moved 0.4 cm,
    /// the root carried 35 cm to its reach and left there, the thigh 7.7° mean off).
    pub(super) fn heading(&self, up: Vec3, rotation: Quat) -> f32 {
        let ahead = rotation * self.heading_local;
        let side = heading_about(up, up.cross(rotation * self.side_local));
        let w = level_weight(ahead, up);
        wrap(side + w * wrap(heading_about(up, ahead) - side))
    }

    /// Takes one more `dt` of a flat stance whose heel stands `height` above the floor (as the
    /// lock rolls the foot) into the heel's standing height: the mean of the frames seen (a
    /// foot's standing height does not change over a performance; an average forgetting after
    /// a second followed each stance's own height and moved the pins from one stance to the
    /// next). Where the rest gives a height (`rest_heel`), that height as long as the mean
    /// lies within the stances' own spread of it, the mean once it lies twice that far,
    /// smoothly between: a floating rest whose heights are right (the CMU-style rigs) keeps
    /// them, where the motion's would move the pins by the stances' spread (live, planted feet
    /// within 1 cm of the source's on 8 pairs fewer), and one whose heights are not (MakeHuman:
    /// its pins up to 9 cm under the animation's standing ankles) takes the motion's.
    pub(super) fn learn_height(&mut self, height: f32, dt: f32) {
        self.stand_secs += dt;
        let k = dt / self.stand_secs;
        self.learnt_mean += k * (height - self.learnt_mean);
        self.learnt_sq += k * (height * height - self.learnt_sq);
        let mean = self.learnt_mean;
        let spread = (self.learnt_sq - mean * mean).max(0.0).sqrt();
        self.heel_clearance = self.heel_from(mean, spread);
    }

    /// The heel's standing height from stances standing at `mean` with `spread`: where the
    /// rest gives one (`rest_heel`), the rest's while the mean lies within the spread of it,
    /// the mean once twice that far ([`Foot::learn_height`]); else the mean.
    pub(super) fn heel_from(&self, mean: f32, spread: f32) -> f32 {
        match self.rest_heel {
            Some(rest) => {
                let d = mean - rest;
                rest + d * ((d.abs() - spread) / spread.max(1e-6)).clamp(0.0, 1.0)
            }
            None => mean,
        }
    }

    /// Takes one more `dt` of a flat stance pitched `pitch` (radians) into the standing pitch
    /// of a foot with no rest to stand it as: the mean of every flat stance frame seen
    /// (`fit_secs` of them, this one counted), a foot's first flat stance setting it at once.
    /// A foot's pitch as it stands does not change over a performance, and the ball's standing
    /// height goes with it ([`FootLock::learn_fit`]): an average forgetting after a second
    /// followed each stance's own pitch, and moved the ball's pin from one stance to the next
    /// (live, in process: the CMU 131_01 walk onto LaFAN1's rig, planted feet 1.13 cm off the
    /// performer's, 0.94 with the mean).
    pub(super) fn learn_standing_pitch(&mut self, pitch: f32, dt: f32) {
        if self.fit_secs > 0.0 {
            self.standing_pitch += dt / self.fit_secs * (pitch - self.standing_pitch);
        }
    }

    /// The foot's length to its ball; `None` without one (the toes not rigged).
    pub(super) fn ball(&self) -> Option<f32> {
        self.leg.toes.map(|_| self.foot_length)
    }

    /// Where a pinned ankle stands, the foot turned as `ball` (ankle to ball, when the foot has
    /// one) says: rolled on its pin ([`Foot::roll`]) from where its heel is pinned, which is its
    /// standing height plus the foot's lift where the source's heel is known (offline), else
    /// where it was pinned, lifted by the foot's own lift.
    /// At the end of a toe-off, raised towards the animation's ankle
    /// ([`Foot::raise_to_animation`]).
    pub(super) fn pinned_ankle(&self, up: Vec3, floor: f32, ball: Option<Vec3>) -> Vec3 {
        let ankle = self.rolled_ankle(up, floor, ball);
        ankle + up * self.raise_to_animation(up, ankle)
    }

    /// [`Foot::pinned_ankle`] before the raise.
    pub(super) fn rolled_ankle(&self, up: Vec3, floor: f32, ball: Option<Vec3>) -> Vec3 {
        let p = self.lock_position;
        let heel = match self.heel_lift {
            Some(_) => p - up * p.dot(up) + up * (floor + self.heel_clearance + self.lift),
            None => p + up * self.lift,
        };
        // Without a ball the ankle rises with the heel, straight up.
        heel + ball.map_or(up * self.heel_rise, |o| self.roll(up, o))
    }

    /// How far a pin whose ankle would stand at `ankle` is raised towards the animation's
    /// ankle: while the foot stands on its ball (`on_ball`), as its lift-off nears
    /// (`release`), up to where the retargeted foot stands, never down. Its ball keeps its
    /// place over the ground and the animation's pitch, and leaves the floor early. A foot
    /// standing steeper than the performer's, or shorter against its leg, raises its ankle
    /// less as it rolls over its ball: pinned on the floor to the end, the ankle stood under
    /// the animation's and the body came down onto it, taking the landing foot under its
    /// floor (the pymo Meredith walk onto the UE-style mannequin, whose foot stands 45° down
    /// against the performer's 15°: that ankle 3.0 cm under the animation's as the toe-off
    /// ended, the animation's ball 3.7 cm up, the body 3.0 cm down, the landing thigh 17° off).
    /// Only as the lift-off nears: a stand on the toes held (the CMU 131_01 walk's final
    /// stand) keeps its ball on the floor.
    pub(super) fn raise_to_animation(&self, up: Vec3, ankle: Vec3) -> f32 {
        let wanted = self.release * self.on_ball * (self.animated_up - ankle.dot(up)).max(0.0);
        wanted.min(self.raise_most)
    }

    /// Live, where the lift-off's foresight is read afresh every sample ([`LiveRelease`]):
    /// bounds this frame's raise ([`Foot::raise_to_animation`]) to last frame's plus what the
    /// pin may rise in `dt`: [`RAISE_LEGS_PER_SEC`] leg lengths a second, or as fast as the
    /// animation lifts the ankle (`animated_up`, this frame's before the root's move onto the
    /// standing feet), whichever is faster. The shown foot then never jumps up as the
    /// foresight's evidence jumps (foot_lock's kick on the Godot robot 15.2 cm/frame² taken at
    /// once, 1.28 in the animation), and a pin may follow an ankle the animation lifts fast
    /// (a jump's toe-off): held to a leg length a second there, Xia's pins were released 1 cm
    /// under the animation's ankles, which the release blend carried on to 1.7 cm (thigh 10°).
    pub(super) fn raise_limit(&mut self, animated_up: f32, dt: f32) {
        let rising = match self.animated_up_before {
            Some(before) if dt > 0.0 => ((animated_up - before) / dt).max(0.0),
            _ => 0.0,
        };
        self.animated_up_before = Some(animated_up);
        let speed = (RAISE_LEGS_PER_SEC * self.leg.length).max(rising);
        self.raise_most = self.raised + speed * dt;
    }

    /// How a planted foot turned as `ball` (ankle to ball) stands on the floor, as a foot does:
    /// on its heel while its ball is no lower against the ankle than when it stands (a heel
    /// strike, toes up: the ankle on its pin), on its ball once it is (the heel rising at a
    /// toe-off: the ball held where standing puts it, the ankle raised and brought towards it
    /// as the foot pitches about the ball). While the source's heel holds, the heel rises only
    /// as far as the source's does (`heel_rise`): a foot the animation points into the floor
    /// while its heel stays down is pitched up about its ankle instead (`flatten`); while the
    /// source stands on its ball alone, as far as the foot's own length asks (`on_ball`). Returns the ankle's move from the heel's
    /// pin. Up to that, the foot keeps the animation's pitch, so the leg above it keeps the
    /// retargeted one's.
    pub(super) fn roll(&self, up: Vec3, ball: Vec3) -> Vec3 {
        let rise = self.ball_clearance - self.heel_clearance;
        let o_up = ball.dot(up);
        // A foot rolled onto its ball while the performer stands on theirs keeps the
        // animation's pitch with its ball where it stood, its ankle raised as far as its own
        // length asks; else the heel rises only as far as the source's does, and a foot
        // pitched further is stood flatter (`flatten`). A target foot longer against its leg
        // than the performer's was flattened up to 30° at a stand on the toes (the CMU 131_01
        // walk onto the xsens rig: its ball 6 cm short of where the source's heel rise puts it).
        let own = rise - o_up;
        let lifted = own.min(self.heel_rise) + self.on_ball * (own - self.heel_rise).max(0.0);
        if !(lifted > 0.0) {
            return Vec3::ZERO;
        }
        let o_flat = ball - up * o_up;
        let Some(dir) = o_flat.try_normalize() else {
            return up * lifted;
        };
        let flat = |rise: f32| {
            (self.foot_length * self.foot_length - rise * rise)
                .max(0.0)
                .sqrt()
        };
        // The ball stays on its pin: the ankle comes forward by how much shorter the foot's
        // reach over the ground is, pitched to stand its heel that high.
        dir * (flat(rise) - flat(rise - lifted)) + up * lifted
    }

    /// The height a pinned foot's ball, `now` at that height, is brought to over a floor at
    /// `floor`: its standing height (plus the foot's lift) where it is lower, else no higher
    /// than the source's ball stands over its own flat standing height (`ball_lift`, offline;
    /// where that is not known, its standing height: stood flat). At a heel strike the
    /// performer's toes come down after the heel, and the foot keeps the animation's pitch
    /// until they have: stood flat at once, LaFAN1's walk onto X Bot had its feet pitched
    /// down onto the floor 3 frames ahead of each plant and for 8 after it, 6-21° off the
    /// performer's.
    pub(super) fn ball_goal(&self, floor: f32, now: f32) -> f32 {
        let lowest = floor + self.ball_clearance + self.lift;
        let highest =
            (self.ball_lift).map_or(lowest, |b| lowest.max(floor + self.ball_clearance + b));
        // A pin raised towards the animation's ankle at the end of a toe-off keeps the
        // animation's pitch: its ball stays up with it, no lower than the raise took it (a
        // foot only partly rolled onto its ball, its ball under its standing height, is
        // pitched up to it as unraised: pitched to the floor's height instead, its ball swung
        // over the ground as the raise grew).
        let highest = highest.max(lowest + self.raised);
        clamp_safe(now, lowest + self.raised, highest)
    }

    /// Takes this frame's lift of the source's foot (its lowest contact over its ground,
    /// scaled, `lift`) and how much higher than that its heel stands (scaled; `None` where the
    /// source's heel is not known): how high the pin is held, how far the heel's pin rises
    /// ([`Foot::pinned_ankle`]) and how far the foot rolls onto its ball ([`Foot::roll`]).
    pub(super) fn take_heel(&mut self, lift: f32, rise: Option<f32>) {
        self.lift = lift;
        // The heel follows how much higher than the foot's lowest contact the source's is
        // (a foot pitched toes-down). As far as keeps the foot level enough to be stood
        // flat ([`FLATTEN_LEVEL`]), its ball on the floor: a foot pitched steeper is no
        // longer brought down onto it. A foot without a ball rises as the source's heel
        // does, up to the source's foot length.
        let most = match self.ball() {
            Some(len) => {
                let steepest = len * (1.0 - FLATTEN_LEVEL * FLATTEN_LEVEL).sqrt();
                (steepest - (self.heel_clearance - self.ball_clearance)).max(0.0)
            }
            None => self.heel_reach,
        };
        self.heel_lift = rise.map(|r| lift + clamp_safe(r, 0.0, most));
        // A foot rolls onto its ball as far as the source's heel rises ([`Foot::roll`]);
        // one without rises with it.
        let rise = rise.unwrap_or(0.0);
        self.heel_rise = match self.ball() {
            Some(_) => rise.max(0.0),
            None => clamp_safe(rise, 0.0, most),
        };
    }

    /// Where along its sole, heel (0) to ball (1), this foot turns with the animation while the
    /// source's foot stands on `contact`: on its ball while only the source's ball holds (its
    /// heel rising: a toe-off, a turn on the ball), where the lock rolls it too
    /// ([`Foot::roll`]); else about the joint it stands on itself, the lower of its heel and
    /// ball when it stands. The lock stands a pinned foot flat ([`FootLock::flatten`]), so
    /// that joint is on the floor whichever of the source's contacts hold: at a heel strike's
    /// pivot the performer's toes are off the ground, the character's are not, and a turn
    /// about the heel swept them over it.
    pub(super) fn pivot_of(&self, contact: Contact) -> f32 {
        match contact {
            Contact::Ball => 1.0,
            _ if self.heel_clearance <= self.ball_clearance => 0.0,
            _ => 1.0,
        }
    }

    /// Turns the pin to `heading` about the point `share` of the way from its heel to its
    /// ball (1: on its ball, as a foot turning on the spot does): the pin moves so that point
    /// stays where the foot stood flat ([`FootLock::flatten`]) puts it. The points of the sole
    /// between heel (under the ankle, which a turn about the up axis leaves in place) and ball
    /// move by a blend of the two ends' moves. `balls`: the ball's offset from the ankle at the
    /// old heading and at the new.
    pub(super) fn turn_about(
        &mut self,
        up: Vec3,
        floor: f32,
        heading: f32,
        balls: Option<(Vec3, Vec3)>,
        share: f32,
    ) {
        if let Some((from, to)) = balls {
            let ball = |o: Vec3| {
                // The raise towards the animation's ankle lifts ankle and ball alike: the
                // ball's reach is the rolled foot's (read from the raised ankle, a pin turning
                // on its ball slid it 1 mm a frame).
                let ankle = self.rolled_ankle(up, floor, Some(o));
                let len = o.length();
                let stand = floor + self.ball_clearance + self.lift;
                let rise = clamp_safe(stand - ankle.dot(up), -len, len);
                let reach = (len * len - rise * rise).max(0.0).sqrt();
                ankle + (o - up * o.dot(up)).normalize_or_zero() * reach
            };
            let moved = (ball(from) - ball(to)) * share;
            self.lock_position += moved - up * moved.dot(up);
        }
        self.lock_heading = heading;
    }

    /// The animated ankle's velocity and heading rate since the last frame, `dt` ago; records
    /// this frame's.
    pub(super) fn animation_moved(&mut self, animated: Vec3, heading: f32, dt: f32) -> (Vec3, f32) {
        let moved = if dt > 0.0 {
            (
                (animated - self.animated_position) / dt,
                wrap(heading - self.animated_heading) / dt,
            )
        } else {
            (Vec3::ZERO, 0.0)
        };
        (self.animated_position, self.animated_heading) = (animated, heading);
        moved
    }

    /// A pin taken or let go: the difference in place and in speed between what is shown and
    /// the new goal (position, heading, velocity, heading rate) is taken up and decays from
    /// here. An unpinned foot is measured from where the hips carry it down (the caller folds
    /// that into the goal's position). A landing foot stops where it is shown (a release
    /// blends in place and speed), except that a foot still coming down onto its pin keeps
    /// that downward speed: stopping it would leave it hanging over the pin for the blend's
    /// length. A foot seen for the first time has shown nothing yet: nothing to blend from.
    /// The difference is taken against where the goal was `dt` ago, as the shown foot is last
    /// frame's: the offset then steps over this frame with the goal (taken against the goal's
    /// place now, a released foot stepped back by the animation's move over the frame before
    /// it swung on, a kick).
    pub(super) fn retake_offsets(
        &mut self,
        fresh: bool,
        up: Vec3,
        goal: (Vec3, f32, Vec3, f32),
        dt: f32,
    ) {
        let (target, target_heading, velocity, rate) = goal;
        let keep_speed = if self.locked { 0.0 } else { 1.0 };
        self.position_offset = if fresh {
            Decay::default()
        } else {
            let value = self.shown_position - (target - velocity * dt);
            let relative = self.shown_velocity - velocity;
            // Only a foot above its goal and coming down: a speed up onto a goal above (or
            // away from one below) carried past it.
            let down = up * relative.dot(up);
            let settling = if relative.dot(up) < 0.0 && value.dot(up) > 0.0 {
                down
            } else {
                Vec3::ZERO
            };
            Decay {
                value,
                velocity: relative * keep_speed + settling * (1.0 - keep_speed),
            }
        };
        self.heading_offset = Decay {
            value: wrap(self.shown_heading - (target_heading - rate * dt)),
            velocity: (self.shown_heading_rate - rate) * keep_speed,
        };
    }
}

/// How a foot stands on one frame: its ankle's height above the floor (metres), its pitch
/// (radians, ball above the ankle positive) and how much higher the source's heel stands than
/// its lowest contact (scaled; 0 where not known).
#[derive(Debug, Clone, Copy)]
pub(super) struct Stance {
    pub(super) ankle: f32,
    pub(super) pitch: f32,
    pub(super) heel_rise: f32,
}

impl Stance {
    /// How far the lock raises the ankle of a foot standing so, rolling it onto its ball
    /// ([`Foot::roll`]): a frame on its ball (pitched lower than `standing` once `fix` is
    /// added, the source's heel up) has it raised by that, as far as the heel rises. `len`:
    /// the foot's length, `None` for a foot without a ball, raised as far as the heel rises.
    pub(super) fn rolled(&self, len: Option<f32>, standing: f32, fix: f32) -> f32 {
        let Some(len) = len else {
            return self.heel_rise.max(0.0);
        };
        (len * (standing.sin() - (self.pitch + fix).sin()))
            .min(self.heel_rise)
            .max(0.0)
    }
}

/// The per-frame goal of one foot.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Goal {
    pub(super) active: bool,
    /// The goal is fixed in the world (locked) rather than carried by the hips.
    pub(super) pinned: bool,
    pub(super) ankle: Vec3,
    pub(super) rotation: Quat,
    /// The ball relative to the ankle (after the heading turn).
    pub(super) ball_offset: Option<Vec3>,
    /// The source's foot is off the ground (the foot swings, or comes down to land).
    pub(super) swinging: bool,
    /// How far the floor's clamp has lifted the ankle goal this frame.
    pub(super) floor_lift: f32,
}

impl Foot {
    /// `leg`'s foot with its ankle at `ankle`, unlocked, nothing lifted, blended or seen yet,
    /// and neutral local axes: what [`standing_foot`] measures from the rig goes on top.
    pub(super) fn unlocked_at(leg: Leg, source: Option<usize>, ankle: Vec3) -> Foot {
        Foot {
            leg,
            source,
            heel_clearance: 0.0,
            ball_clearance: 0.0,
            foot_length: 0.0,
            standing_pitch: 0.0,
            pitch_fix: 0.0,
            fit_secs: 0.0,
            fit: FitMedian::default(),
            learns_heights: false,
            stand_secs: 0.0,
            heights_held: false,
            stance_heel: Moments::default(),
            first_heel: 0.0,
            later_heel: Moments::default(),
            relearnt: false,
            learnt_mean: 0.0,
            learnt_sq: 0.0,
            rest_heel: None,
            side_local: Vec3::Z,
            heading_local: Vec3::X,
            pole_local: Vec3::X,
            locked: false,
            lift: 0.0,
            heel_lift: None,
            ball_standing: None,
            ball_lift: None,
            heel_rise: 0.0,
            on_ball: 0.0,
            heel_reach: 0.0,
            landing: 0.0,
            landing_flat: 0.0,
            landing_before: 0.0,
            lock_position: ankle,
            lock_heading: 0.0,
            pivot: None,
            contact: None,
            pin_moved: Vec3::ZERO,
            position_offset: Decay::default(),
            heading_offset: Decay::default(),
            flat_offset: Decay::default(),
            shown_flat: 0.0,
            toes_up: 0.0,
            shown_position: ankle,
            shown_velocity: Vec3::ZERO,
            shown_heading: 0.0,
            shown_heading_rate: 0.0,
            animated_position: ankle,
            animated_heading: 0.0,
            seen: false,
            raw_ankle: ankle,
            animated_up: 0.0,
            release: 0.0,
            raised: 0.0,
            raise_most: f32::INFINITY,
            animated_up_before: None,
            carried: None,
            aside: Decay::default(),
            aside_wanted: Vec3::ZERO,
        }
    }
}
