//! In-place clips: a walk animated on the spot (the usual game-asset "in place" walk, every
//! Quaternius animal, the glTF Fox) never moves its root, so a standing foot is not still: it
//! slides backwards under the body, as on a treadmill, and a detector that asks for a still
//! foot finds no plant at all.
//!
//! The belt is read from the motion: on most frames of a gait some foot stands, and the
//! lowest contact joint is the likeliest to. The median of the lowest joint's horizontal
//! velocity over the clip is the ground's velocity under the body: about zero for a clip that
//! travels (its standing feet are still), the belt for an in-place one. Animated belts are
//! not steady (a Quaternius horse's standing hoof slides back at 0.6–2.9 m/s through one
//! stance), so a clip counts as in place when the belt is clear (faster than the detector's
//! "slow"), most frames' lowest joint moves its way, and no foot ends the clip far from where
//! it began (a travelling run's lowest foot is often a swinging one, but its feet go with the
//! body); the detector then reads a foot low
//! in its range ([`stance_band`]) and not moving against the belt as standing
//! ([`Contacts::speed`]).

use glam::Vec3;

/// Share of frames whose lowest contact joint must move the belt's way (the standing feet of
/// a gait) for a clip to count as in place.
const MIN_AGREEING: f32 = 0.6;

/// The farthest a foot of an in-place clip gets from where it started, over the clip, as a
/// speed relative to the belt's: a looping stride ends where it began (about 0), a clip cut
/// mid-stride ends at most a stride away.
const MAX_TRAVEL: f32 = 0.5;

/// Contact joint positions over a clip, joint-major (`pos[j * frames + i]`), as the detector
/// lays them out.
pub(crate) struct Contacts<'a> {
    pub pos: &'a [Vec3],
    pub frames: usize,
    pub dt: f32,
    /// Half-width of the centred velocity window, frames.
    pub half: usize,
    pub up: Vec3,
}

impl Contacts<'_> {
    fn joints(&self) -> usize {
        self.pos.len().checked_div(self.frames).unwrap_or(0)
    }

    fn at(&self, j: usize, i: usize) -> Vec3 {
        self.pos[j * self.frames + i]
    }

    /// Centred velocity of joint `j` at frame `i`.
    fn velocity(&self, j: usize, i: usize) -> Option<Vec3> {
        let (a, b) = (
            i.saturating_sub(self.half),
            (i + self.half).min(self.frames.saturating_sub(1)),
        );
        if b <= a {
            return None;
        }
        Some((self.at(j, b) - self.at(j, a)) / ((b - a) as f32 * self.dt))
    }

    /// Centred horizontal velocity of joint `j` at frame `i`.
    fn horizontal_velocity(&self, j: usize, i: usize) -> Option<Vec3> {
        let v = self.velocity(j, i)?;
        Some(v - self.up * v.dot(self.up))
    }

    /// Joint `j`'s speed at frame `i` as the detector reads it: its whole speed, or on a
    /// `belt` its speed against the belt (swinging forward). Animated belts are unsteady (a
    /// standing hoof of a Quaternius horse slides back at 0.5–2.4 × the median), and a paw
    /// rolling over or being picked up slows or sways sideways (an in-place body does not
    /// sway, so a standing paw does relative to it): so moving back at any speed stands, and
    /// how high the joint rides is left to the stance band. Infinite where no window fits.
    pub fn speed(&self, j: usize, i: usize, belt: Option<Vec3>) -> f32 {
        let Some(v) = self.velocity(j, i) else {
            return f32::INFINITY;
        };
        match belt {
            Some(b) => (-v.dot(b.normalize_or_zero())).max(0.0),
            None => v.length(),
        }
    }

    /// The joint lowest above its own lowest level at frame `i`.
    fn lowest(&self, i: usize, floors: &[f32]) -> usize {
        (0..self.joints())
            .min_by(|&a, &b| {
                let h = |j: usize| self.at(j, i).dot(self.up) - floors[j];
                h(a).total_cmp(&h(b))
            })
            .unwrap_or(0)
    }
}

/// The ground's horizontal velocity under an in-place clip (m/s in the clip's units), `None`
/// for a clip that travels or shows no steady belt. `slow`: the detector's speed below which
/// a foot counts as still.
pub(crate) fn belt_velocity(c: &Contacts<'_>, slow: f32) -> Option<Vec3> {
    if c.frames < 3 || c.joints() == 0 {
        return None;
    }
    let floors: Vec<f32> = (0..c.joints())
        .map(|j| {
            (0..c.frames)
                .map(|i| c.at(j, i).dot(c.up))
                .fold(f32::INFINITY, f32::min)
        })
        .collect();
    let samples: Vec<Vec3> = (0..c.frames)
        .filter_map(|i| c.horizontal_velocity(c.lowest(i, &floors), i))
        .collect();
    let belt = median(&samples)?;
    // Feet that travel with the body (a capture moving across the room) are no belt's, even
    // when the lowest foot is often a swinging one (a run's flight).
    let duration = (c.frames - 1) as f32 * c.dt;
    let travel = (0..c.joints())
        .map(|j| {
            let d = c.at(j, c.frames - 1) - c.at(j, 0);
            (d - c.up * d.dot(c.up)).length() / duration
        })
        .fold(0.0, f32::max);
    if travel > MAX_TRAVEL * belt.length() {
        return None;
    }
    let along = belt.normalize_or_zero();
    let with_belt = samples.iter().filter(|v| v.dot(along) > 0.5 * slow).count();
    let steady = with_belt as f32 >= MIN_AGREEING * samples.len() as f32;
    (belt.length() >= slow && steady).then_some(belt)
}

/// How high above its ground joint `j` of an in-place clip may ride while it stands: half its
/// clip's height range. A leg whose lowest joint is a hock or a fetlock well above the hoof
/// (the rig has no bone at the contact) lifts that joint as the leg rolls over the standing
/// hoof; on a belt, moving the belt's way in the lower half of its range is standing.
pub(crate) fn stance_band(c: &Contacts<'_>, j: usize, ground: f32) -> f32 {
    let top = (0..c.frames)
        .map(|i| c.at(j, i).dot(c.up))
        .fold(f32::NEG_INFINITY, f32::max);
    0.5 * (top - ground).max(0.0)
}

/// Component-wise median.
fn median(v: &[Vec3]) -> Option<Vec3> {
    if v.is_empty() {
        return None;
    }
    let mut c = vec![0.0f32; v.len()];
    let mut mid = |f: fn(&Vec3) -> f32| {
        for (x, p) in c.iter_mut().zip(v) {
            *x = f(p);
        }
        *c.select_nth_unstable_by(v.len() / 2, f32::total_cmp).1
    };
    Some(Vec3::new(mid(|p| p.x), mid(|p| p.y), mid(|p| p.z)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two feet on a belt moving at −1 m/s along x: each stands (slides back with the belt,
    /// on the ground) for half the cycle and swings forward, 10 cm up, for the other half.
    fn belt_walk(frames: usize, dt: f32, travel: f32) -> Vec<Vec3> {
        let period = 30;
        let mut pos = Vec::new();
        for phase in [0, period / 2] {
            for i in 0..frames {
                let t = (i + phase) % period;
                let half = period / 2;
                let (x, y) = if t < half {
                    (0.25 - t as f32 * dt, 0.0)
                } else {
                    let s = (t - half) as f32 / half as f32;
                    (
                        0.25 - half as f32 * dt + s * half as f32 * dt,
                        0.1 * (s * std::f32::consts::PI).sin(),
                    )
                };
                pos.push(Vec3::new(x + travel * i as f32 * dt, y, 0.0));
            }
        }
        pos
    }

    fn contacts(pos: &[Vec3], frames: usize, dt: f32) -> Contacts<'_> {
        Contacts {
            pos,
            frames,
            dt,
            half: 1,
            up: Vec3::Y,
        }
    }

    #[test]
    fn an_in_place_walk_shows_its_belt() {
        let dt = 1.0 / 30.0;
        let pos = belt_walk(90, dt, 0.0);
        let belt = belt_velocity(&contacts(&pos, 90, dt), 0.2).expect("a belt");
        assert!((belt - Vec3::new(-1.0, 0.0, 0.0)).length() < 0.05, "{belt}");
    }

    #[test]
    fn a_travelling_walk_has_no_belt() {
        let dt = 1.0 / 30.0;
        // The same gait with the body carried forward at the belt's speed: standing feet still.
        let pos = belt_walk(90, dt, 1.0);
        assert_eq!(belt_velocity(&contacts(&pos, 90, dt), 0.2), None);
    }

    #[test]
    fn feet_waving_at_random_show_no_steady_belt() {
        let dt = 1.0 / 30.0;
        let mut pos = Vec::new();
        for j in 0..2 {
            for i in 0..90 {
                let a = (i * (7 + j * 5)) as f32 * 0.37;
                pos.push(Vec3::new(
                    a.sin() * 0.3,
                    0.05 * a.cos().abs(),
                    a.cos() * 0.3,
                ));
            }
        }
        assert_eq!(belt_velocity(&contacts(&pos, 90, dt), 0.2), None);
    }
}
