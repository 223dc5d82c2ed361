//! How near a source foot's next plant or its lift-off is: offline from the plants ahead
//! ([`landing_weight`], [`release_weight`]), live from how fast the heel comes down
//! ([`LiveLanding`]); what a source foot stands above its ground this frame ([`Lifts`]).

use super::*;

/// Per source leg, how high its foot (its lowest contact) and its heel stand above their
/// grounds this frame (source units), and how near its next plant is ([`landing_weight`]).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Lifts {
    pub(super) foot: [f32; MAX_FEET],
    pub(super) heel: [f32; MAX_FEET],
    /// Offline: how high its ball stands above its ground (its heel's where it has none).
    pub(super) ball: Option<[f32; MAX_FEET]>,
    pub(super) landing: [f32; MAX_FEET],
    /// How near each source foot's lift-off is (offline, [`release_weight`]; live,
    /// [`LiveRelease`]).
    pub(super) release: [f32; MAX_FEET],
    /// The ball comes down with the ankle ahead of a plant (offline, where the plant is
    /// known; live the foot keeps the animation's pitch, toes up for a heel strike: a ball
    /// pitched down onto a guess of the landing kicked the toes).
    pub(super) landing_flat: bool,
    /// Which of each source foot's contacts hold this frame ([`PlantTrack::contacts`]).
    pub(super) contact: [Option<Contact>; MAX_FEET],
}

/// Offline, where the plants ahead are known: how far a foot not planted on `frame` is brought
/// down to the height its pin will have, 0 (no plant within `lead` frames) rising smoothly to 1
/// on the frame before the plant. A lock that only starts blending when the source's foot lands
/// leaves the target's foot settling onto the floor for the blend's length while the source's
/// already stands (a rig whose legs are built differently holds its feet higher in the swing).
/// Only after a swing at least twice the lead: a foot released a moment ago is still blending
/// back to the animation, and bending its path down again at once kicks it.
pub(super) fn landing_weight(plants: &PlantTrack, frame: usize, leg: usize, lead: usize) -> f32 {
    if lead == 0 || plants.is_planted(frame, leg) {
        return 0.0;
    }
    let last = plants.num_frames();
    let Some(k) = (1..=lead).find(|k| frame + k < last && plants.is_planted(frame + k, leg)) else {
        return 0.0;
    };
    // The swing runs from after the previous plant to frame + k.
    let swing_start = (frame + k).saturating_sub(2 * lead);
    if (swing_start..frame).any(|f| plants.is_planted(f, leg)) {
        return 0.0;
    }
    let t = (lead + 1 - k) as f32 / lead as f32;
    t * t * (3.0 - 2.0 * t)
}

/// Offline, where the plants ahead are known: how near the lift-off of `leg`'s foot planted on
/// `frame` is, 0 (lifted more than `lead` frames later, or not within the clip) rising smoothly
/// to 1 on its last planted frame; 0 where it is not planted. How far a pin on its ball is
/// raised towards the animation's ankle ([`Foot::raise_to_animation`]): the end of a toe-off,
/// not a stand on the toes.
pub(super) fn release_weight(plants: &PlantTrack, frame: usize, leg: usize, lead: usize) -> f32 {
    if lead == 0 || !plants.is_planted(frame, leg) {
        return 0.0;
    }
    let last = plants.num_frames();
    let lifted = |k: usize| frame + k + 1 < last && !plants.is_planted(frame + k + 1, leg);
    let Some(k) = (0..lead).find(|&k| lifted(k)) else {
        return 0.0;
    };
    let t = (lead - k) as f32 / lead as f32;
    t * t * (3.0 - 2.0 * t)
}

/// Live, where the lift-offs are not known: per source leg, how near its planted foot's
/// lift-off looks, as [`release_weight`] is offline. While the source stands on its ball
/// alone (its heel up: a toe-off), from whichever of the detector's two release tests its
/// ball nears first: how far its speed has come towards the speed a planted foot is let go
/// at, or how soon its lowest contact's height or its speed reaches its bound at its present
/// rate (a toe-off's ball pivots, then pushes off: Xia's walk let its feet go by speed, the
/// ball never rising towards the height); 0 while it stands otherwise.
///
/// Read afresh on every sample, up and down, and not held nor ramped: what keeps the shown
/// foot smooth is the limit on how fast its pin rises ([`Foot::raise_limit`]). A weight
/// from the rates alone, ramped no faster than over the blends' time, came too late: a
/// toe-off's ball speeds up in steps (Xia's: 0.34, 0.43, 0.48, 0.46, 0.46, 0.66, 1.15 of the
/// release speed at 120 fps, released 0.06 s after its heel rose), so the rate's foresight
/// fired a few samples before the release and the ramp reached 0.2-0.5: the pins on their
/// balls stayed 1-2 cm under the animation's rising ankles, and released there, under an
/// animation speeding up, the legs stood 8-11° off for 0.1 s (Xia onto X Bot), or held the
/// body down while the other foot landed (the pymo Meredith walk onto X Bot). Held once
/// foreseen, a stand on the toes whose ball wanders at a share of the release speed (the CMU
/// 131_01 walk's final stand) kept its ball raised off the floor (the mannequin's planted
/// feet 0.58 -> 1.02 cm off their standing height).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LiveRelease {
    /// The foot's lowest contact above its ground at the last sample (source units).
    pub(super) low: [f32; MAX_FEET],
    /// Its ball's speed over the release speed at the last sample.
    pub(super) speed: [f32; MAX_FEET],
    pub(super) weight: [f32; MAX_FEET],
}

impl LiveRelease {
    /// Takes a new source sample `dt` after the last: per leg its plant, which of its contacts
    /// hold, its lowest contact's height above its ground, the height the detector lets a
    /// planted foot go at (`high`) and its ball's speed over the speed it is let go at
    /// (`speeds`). Each weight is, smoothly from 0 to 1, the most of: the ball's speed over the
    /// release speed, and how far the time the height or the speed takes to reach its bound at
    /// its present rate has come down from `lead` seconds to none (as offline).
    pub(super) fn update(
        &mut self,
        planted: &[bool],
        contacts: &[Option<Contact>],
        (lifts, speeds): (&[f32], &[f32]),
        high: &[f32],
        dt: f32,
        lead: f32,
    ) {
        let smooth = |t: f32| {
            let t = t.clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        };
        let soon = |now: f32, before: f32, bound: f32| {
            let rate = if dt > 0.0 { (now - before) / dt } else { 0.0 };
            if !(rate > 0.0 && lead > 0.0) {
                return 0.0;
            }
            smooth(1.0 - (bound - now).max(0.0) / (rate * lead))
        };
        for (s, ((&p, &lift), &high)) in planted.iter().zip(lifts).zip(high).enumerate() {
            let speed = speeds.get(s).copied().unwrap_or(0.0);
            let rising = soon(lift, self.low[s], high);
            let speeding = soon(speed, self.speed[s], 1.0);
            (self.low[s], self.speed[s]) = (lift, speed);
            let on_ball = contacts.get(s).copied().flatten() == Some(Contact::Ball);
            self.weight[s] = if p && on_ball {
                smooth(speed).max(rising).max(speeding)
            } else {
                0.0
            };
        }
    }
}

/// Live, where the plants ahead are not known: per source leg, how near its foot's next
/// plant looks from how fast it comes down, as [`landing_weight`] is offline.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LiveLanding {
    /// The heel above its ground at the last sample (source units).
    pub(super) lift: [f32; MAX_FEET],
    /// The heel has been up past the detector's height bound since its last plant (a swing,
    /// not the shuffle of a foot that never left the ground, nor one just lifted).
    pub(super) swung: [bool; MAX_FEET],
    pub(super) weight: [f32; MAX_FEET],
}

impl LiveLanding {
    /// Takes a new source sample `dt` after the last: per leg its plant, its heel's height
    /// above its ground and the height above which a heel has swung (`near`). Each weight
    /// rises from 0 to 1 as the time the heel takes to reach its ground at its present speed
    /// comes down from `lead` seconds to none (smoothly, as offline), and fades out as a blend
    /// does when the heel rises again past `near`. The heel, not the lowest contact: a walk's
    /// toes pass a centimetre or two over the ground in mid-swing, coming down fast.
    pub(super) fn update(
        &mut self,
        planted: &[bool],
        lifts: &[f32],
        near: &[f32],
        dt: f32,
        lead: f32,
    ) {
        for (s, ((&p, &lift), &near)) in planted.iter().zip(lifts).zip(near).enumerate() {
            let falling = if dt > 0.0 {
                (self.lift[s] - lift) / dt
            } else {
                0.0
            };
            self.lift[s] = lift;
            if p {
                (self.swung[s], self.weight[s]) = (false, 0.0);
                continue;
            }
            self.swung[s] |= lift > near;
            let soon = if self.swung[s] && falling > 0.0 && lead > 0.0 {
                let t = (1.0 - lift.max(0.0) / (falling * lead)).clamp(0.0, 1.0);
                t * t * (3.0 - 2.0 * t)
            } else {
                0.0
            };
            // Held while the heel stays near its ground: it may stop there, or bob up a few
            // millimetres, until the foot is slow enough to stand (offline the approach holds
            // until the plant). Faded out there, the CMU 131_01 walk's left heel hovering
            // 1.1-1.7 cm up for 0.13 s before its plant at 6.0 s left the Godot robot's body
            // 5 cm under that foot's pin as it landed, its thigh 15-20° off for 0.2 s. Faded
            // out as a blend is once the heel rises again past `near`: the swing goes on.
            let kept = if falling >= 0.0 || lift <= near {
                self.weight[s]
            } else {
                self.weight[s] * (-dt * std::f32::consts::LN_2 / (0.5 * lead)).exp()
            };
            self.weight[s] = soon.max(kept);
        }
    }
}
