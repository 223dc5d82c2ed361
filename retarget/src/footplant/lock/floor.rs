//! No foot under the floor, and the hips' height: a goal raised (a free foot's lift shared
//! between its leg and its pitch, [`split_lift`], and taken where its leg turns least,
//! [`lift_aside`]), the hips raised when every foot sank and lowered when a pinned goal is out
//! of reach.

use super::*;
use crate::footplant::search::least_between;

/// How much of `need` (how far a free foot's ball, `o` from its ankle, is under the floor) its
/// ankle goal `goal` is lifted, the rest taken by pitching the ball up about the ankle: the
/// share whose squared turns of thigh and shin (from the animation's leg, `leg`: hip, knee,
/// ankle and the side the knee bends to) and of the foot's pitch add up least, as the body's
/// height shares a difference between legs (`pelvis`). A swinging foot longer against its leg
/// than the performer's, pointed down, passes its toes under the floor: pitched up alone it
/// was 20-35° off the performer's for the 0.1 s after each lift-off (LaFAN1's walk onto
/// Mousey, its p95 19.5°), where its bent leg takes most of it for a few degrees.
pub(super) fn split_lift(leg: [Vec3; 4], goal: Vec3, o: Vec3, up: Vec3, need: f32) -> f32 {
    let [hip, knee, ankle, pole] = leg;
    let (len, rise) = (o.length().max(1e-6), o.dot(up));
    // The pitch as the foot turns: down to straight down (a foot pointed steeper than
    // `MAX_BALL_RISE` is pitched up from where it points, `pitch_ball`), up to what pitching
    // may give. Clamped at `MAX_BALL_RISE` below too, a foot pointed 60-80° down (Mousey's
    // long foot after a lift-off under LaFAN1's walk) read its first turns up as free, and was
    // pitched up alone, 20-25° off the performer's.
    let pitch = |r: f32| (r / len).clamp(-1.0, MAX_BALL_RISE).asin();
    let sq = |a: f32| if a.is_finite() { a * a } else { 0.0 };
    let cost = |lift: f32| {
        let s = solve_bounded(hip, knee, ankle, goal + up * lift, pole);
        let thigh = (knee - hip).angle_between(s.knee - hip);
        let shin = (ankle - knee).angle_between(s.ankle - s.knee);
        sq(thigh) + sq(shin) + sq(pitch(rise + need - lift) - pitch(rise))
    };
    // One minimum over [0, need]: each part's cost grows with its share.
    least_between(cost, 0.0, need.max(0.0), 0, SPLIT_STEPS)
}

/// Golden-section steps of [`split_lift`] (the bracket shrinks 0.618 a step: 16 steps leave
/// under a thousandth of it).
pub(super) const SPLIT_STEPS: usize = 16;

/// Coarse samples of [`lift_aside`]'s bracket before its golden-section steps.
const ASIDE_SCAN: usize = 9;

/// How far over the ground, along its leg's bend side, a free foot's goal lifted onto the
/// floor (`goal`) is moved: the move within `reach` either way whose squared thigh and shin
/// turns (from the animation's leg, `leg`: hip, knee, ankle and the side the knee bends to;
/// a goal out of reach costing as in `pelvis`, `length` the leg's) add up least, as the
/// body's height shares a difference between legs. Lifted straight up, the lift is taken in
/// the knee's bend alone, which turns a short upper bone far: the Godot robot's thighs are
/// short, and under LaFAN1's walk its swinging foot passes 2-3.6 cm under its floor; lifted
/// straight up, that thigh was 11-16° off the performer's, the shin 4-5°. Turning the leg
/// about the hip too (the foot a few centimetres ahead or behind in the air, where nothing
/// holds it) lifts it for less turn of either bone.
pub(super) fn lift_aside(leg: [Vec3; 4], goal: Vec3, up: Vec3, reach: f32, length: f32) -> Vec3 {
    let [hip, knee, ankle, pole] = leg;
    let Some(axis) = (pole - up * pole.dot(up)).try_normalize() else {
        return Vec3::ZERO;
    };
    let sq = |a: f32| if a.is_finite() { a * a } else { 0.0 };
    let cost = |d: f32| {
        let to = goal + axis * d;
        let s = solve_bounded(hip, knee, ankle, to, pole);
        let thigh = (knee - hip).angle_between(s.knee - hip);
        let shin = (ankle - knee).angle_between(s.ankle - s.knee);
        let miss = pelvis::MISS_RAD_PER_LEG * (to - s.ankle).length() / length.max(1e-6);
        sq(thigh) + sq(shin) + sq(miss)
    };
    if !(reach > 0.0) {
        return Vec3::ZERO;
    }
    // The cost need not have one minimum over the whole bracket: a coarse scan first.
    let d = least_between(cost, -reach, reach, ASIDE_SCAN, SPLIT_STEPS);
    if cost(d) < cost(0.0) {
        axis * d
    } else {
        Vec3::ZERO
    }
}

impl FootLock {
    /// Raises goal `i` so heel and ball stay above the floor, after the hips came down by
    /// `drop` (which carries the animated share of the goal down with them). `live`: a
    /// swinging foot's ball is pitched up alone (see below).
    pub(super) fn clamp_to_floor(&mut self, i: usize, drop: f32, live: bool) {
        let f = &self.feet[i];
        let g = &mut self.goals[i];
        if !g.pinned {
            g.ankle -= self.up * drop;
        }
        if !f.stands_known() {
            return;
        }
        let up = self.up;
        let heel_low = self.floor + f.heel_clearance - g.ankle.dot(up);
        if heel_low > 0.0 {
            g.ankle += up * heel_low;
            g.active = true;
            g.floor_lift += heel_low;
        }
        // A ball below the floor pitches the foot up about the ankle (as a foot rolls onto its
        // heel) rather than lifting the ankle: lifting it would make the knee take up the
        // whole difference, and a rig whose foot points steeply down (its ankle joint on the
        // ground when it stands) would have its leg folded over. Only what pitching cannot
        // give (a ball more than the foot's length too low) lifts the ankle. Offline, a
        // swinging foot shares the need between its leg and its pitch ([`split_lift`]). Live
        // the detector plants a foot a frame or two late, and the share, moving with the
        // leg, slid feet the performer already stood on (the causal lock in process: the CMU
        // run onto the pybvh example rig 0.000 -> 0.065 cm/frame, onto the CMU 31-joint rig
        // 0.025 -> 0.062, though the foot within its bound on 33 -> 38 of 84 pairs).
        let Some(o) = g.ball_offset else { return };
        let need = self.floor + f.ball_clearance - (g.ankle + o).dot(up);
        if need <= 0.0 {
            return;
        }
        let goal = *g;
        let lifted = if goal.pinned || !goal.swinging || live {
            0.0
        } else {
            self.free_lift(i, &goal, o, need)
        };
        let g = &mut self.goals[i];
        g.ankle += up * lifted;
        g.floor_lift += lifted;
        let need = need - lifted;
        let rise = o.dot(up);
        let reached = pitch_ball(g, up, rise + need);
        let rest = need - (reached - rise);
        if rest > 0.0 {
            g.ankle += up * rest;
        }
        g.active = true;
    }

    /// Offline, moves foot `i`'s swinging goal, lifted onto the floor this frame, over the
    /// ground to where its leg turns least ([`lift_aside`], within `max_drift_ratio` of its
    /// leg: no farther than a lock lets a foot stray from the animation), less as its landing
    /// nears (none on the last frame before it: it is pinned under the animation's foot, as
    /// without the move). The move shown follows the one wanted with the blends' spring: the
    /// one wanted changes as fast as the animated foot dips under the floor and comes out
    /// (shown at once, the feet kicked: the built-in mannequin's largest kick under the CMU
    /// walk 1.62 -> 5.17 cm/frame², RobotExpressive's 2.57 -> 11.9). `worlds` hold the
    /// animation's leg, brought down with the hips. Live the detector plants a foot a frame
    /// or two late, and the move slid feet the performer already stood on (the causal lock
    /// in process: drift within its bound on 127 -> 125 pairs, dazfriendly's walk onto
    /// RobotExpressive 0.009 -> 0.086 cm/frame).
    pub(super) fn step_aside(&mut self, i: usize, dt: f32, live: bool) {
        let g = &self.goals[i];
        let f = &self.feet[i];
        if live || g.pinned {
            let f = &mut self.feet[i];
            (f.aside, f.aside_wanted) = (Decay::default(), Vec3::ZERO);
            return;
        }
        let wanted = if g.swinging && g.floor_lift > 0.0 {
            let p = |b: BoneId| self.worlds[b.index()].translation;
            let (hip, knee, ankle) = (p(f.leg.upper), p(f.leg.lower), p(f.leg.foot));
            let pole = f.pole(
                [hip, knee, ankle],
                self.worlds[f.leg.upper.index()].rotation,
            );
            let length = f.leg.length;
            let reach = self.settings.max_drift_ratio * length;
            lift_aside([hip, knee, ankle, pole], g.ankle, self.up, reach, length)
        } else {
            Vec3::ZERO
        };
        let halflife = 0.5 * self.settings.blend_secs;
        let f = &mut self.feet[i];
        // The offset from the move wanted keeps the move shown where it was, then decays.
        f.aside.value += f.aside_wanted - wanted;
        f.aside_wanted = wanted;
        f.aside.step(dt, halflife);
        let shown = (wanted + f.aside.value) * (1.0 - f.landing).clamp(0.0, 1.0);
        if shown != Vec3::ZERO {
            let g = &mut self.goals[i];
            g.ankle += shown;
            g.active = true;
        }
    }

    /// How far foot `i`'s free goal `g`, its ball (`o` from the ankle) `need` under the floor,
    /// has its ankle lifted rather than its ball pitched up ([`split_lift`]); `worlds` hold
    /// the animation's leg.
    pub(super) fn free_lift(&self, i: usize, g: &Goal, o: Vec3, need: f32) -> f32 {
        let f = &self.feet[i];
        let p = |b: BoneId| self.worlds[b.index()].translation;
        let (hip, knee, ankle) = (p(f.leg.upper), p(f.leg.lower), p(f.leg.foot));
        let pole = f.pole(
            [hip, knee, ankle],
            self.worlds[f.leg.upper.index()].rotation,
        );
        split_lift([hip, knee, ankle, pole], g.ankle, o, self.up, need)
    }

    /// Raises the root when every foot would otherwise have to be pulled up: each pinned one
    /// towards its pin, each other one onto the floor. The animation has then sunk the whole
    /// character (a rig whose legs come out longer than the scaled hips' height allows), and
    /// bending the knees to take that up folds short leg bones over; lifting the body keeps
    /// the legs as animated. (With a foot in the air nothing is raised: lifting the body then
    /// lifts the feet about to land too.) Unpinned goals, carried by the hips, move up with
    /// them. Returns whether the root moved.
    pub(super) fn raise_hips(&mut self, out: &mut Pose) -> bool {
        let Some(root) = self.root else {
            return false;
        };
        let up = self.up;
        let mut raise = f32::INFINITY;
        let mut limit = f32::INFINITY;
        for (foot, goal) in self.feet.iter().zip(&self.goals) {
            limit = limit.min(self.settings.max_drop_ratio * foot.leg.length);
            let need = if goal.pinned {
                (goal.ankle - foot.animated_position).dot(up)
            } else if !foot.stands_known() {
                0.0
            } else {
                self.floor + foot.heel_clearance - goal.ankle.dot(up)
            };
            raise = raise.min(need);
        }
        let raise = raise.min(limit);
        if raise.is_nan() || raise <= 0.0 {
            return false;
        }
        for g in self.goals.iter_mut().take(self.feet.len()) {
            if !g.pinned {
                g.ankle += up * raise;
            }
        }
        let parent = match self.target.parent(root) {
            Some(p) => self.worlds[p.index()].rotation,
            None => Quat::IDENTITY,
        };
        out.translations[root.index()] += parent.inverse() * (up * raise);
        true
    }

    /// Lowers the root so every pinned goal is within its leg's reach; returns by how much.
    /// The hips come down at once (a pinned foot must stay reachable) but go back up through
    /// a decaying offset, so a release does not pop the body up.
    pub(super) fn lower_hips(&mut self, out: &mut Pose, dt: f32) -> f32 {
        let Some(root) = self.root else {
            return 0.0;
        };
        let mut drop: f32 = 0.0;
        let mut limit = f32::INFINITY;
        for foot in &self.feet {
            limit = limit.min(self.settings.max_drop_ratio * foot.leg.length);
        }
        for (foot, goal) in self.feet.iter().zip(&self.goals) {
            // Only pinned goals: the others come down with the hips, so lowering cannot help.
            if !goal.pinned {
                continue;
            }
            let p = |b: BoneId| self.worlds[b.index()].translation;
            let (hip, knee, ankle) = (p(foot.leg.upper), p(foot.leg.lower), p(foot.leg.foot));
            let full = (knee - hip).length() + (ankle - knee).length();
            // As far as the solver stretches, or as the animation already does.
            let reach = (full * MAX_EXTENSION).max((ankle - hip).length().min(full)) * 0.999;
            let r = hip - goal.ankle;
            let r_up = r.dot(self.up);
            let r_flat2 = (r.length_squared() - r_up * r_up).max(0.0);
            if r.length() > reach {
                let need = r_up - (reach * reach - r_flat2).max(0.0).sqrt();
                drop = drop.max(need);
            }
        }
        let required = clamp_safe(drop, 0.0, limit);
        let above = self.last_drop - required;
        let drop = if above > 0.0 {
            self.drop_offset.value = above;
            self.drop_offset.step(dt, 0.5 * self.settings.blend_secs);
            required + self.drop_offset.value.max(0.0)
        } else {
            self.drop_offset = Decay::default();
            required
        };
        if drop <= 0.0 {
            return 0.0;
        }
        let parent = match self.target.parent(root) {
            Some(p) => self.worlds[p.index()].rotation,
            None => Quat::IDENTITY,
        };
        out.translations[root.index()] -= parent.inverse() * (self.up * drop);
        drop
    }
}
