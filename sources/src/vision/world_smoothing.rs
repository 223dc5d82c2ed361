//! The world output's own smoothing, once [`super::perspective`] has put every point in the
//! camera's axes, at the body's size in metres.
//!
//! The earlier filters smooth what the model reads (the image landmarks, whose across-picture
//! shape the world output takes, and the world landmarks, whose depth it keeps) in each one's
//! units. What reaches the output is a combination of both, and its jitter was well above
//! MediaPipe's where the frame rate is low or points are hidden (the desk set's seated man at
//! 6 fps, his hands below the desk's edge: a tenth of the points read at visibility under
//! one half carried a quarter of the jitter). This stage smooths the output itself with the
//! One Euro filter MediaPipe's pose graph runs on its world landmarks
//! ([`OneEuroParams::WORLD_OUTPUT`]), in three ways shaped by what the model says rather than
//! by a constant:
//!
//! - each point's reading counts by its visibility: a point the model does not see is a
//!   guess that jumps from frame to frame (its speed estimate and its value move only that
//!   share of the way), and holding it is what the solver does with such a bone anyway;
//! - it follows each point about the torso's seen middle (the shoulders and hips, each by its
//!   visibility), not the hips' centre the output is drawn around: where the hips are hidden
//!   (a seated person, a close webcam) their guessed centre jitters, and filtered about it
//!   every point's share of that jitter would read as speed and open the filter;
//! - one cutoff serves the whole body, from its points' mean speed (each by its visibility):
//!   cut separately, a change that moves every point alike (the person's distance read anew
//!   when a hand drops out of view, which rescales the body across the picture) would be
//!   followed at a different pace by each point and bend the bones between them, and a bone
//!   whose own landmarks stay seen would turn with a hidden hand.
//!
//! The output stays centred on the hips as before: the stage moves the points relative to
//! each other, never the hips' centre.

use glam::Vec3;

use super::landmarks::{idx, Landmarks, NUM_LANDMARKS};
use super::one_euro::{alpha, OneEuroParams};
use super::sides::LR_PAIRS;

/// The torso's corners, whose seen middle the filters follow the body about.
const TORSO: [usize; 4] = [
    idx::LEFT_SHOULDER,
    idx::RIGHT_SHOULDER,
    idx::LEFT_HIP,
    idx::RIGHT_HIP,
];

/// Each body landmark's filtered place and speed about the torso's seen middle. Allocates
/// nothing.
#[derive(Debug, Clone)]
pub struct WorldSmoothing {
    params: OneEuroParams,
    place: [Vec3; NUM_LANDMARKS],
    speed: [Vec3; NUM_LANDMARKS],
    /// When the last frame was seen; `None` before the first (or after a reset).
    last_secs: Option<f64>,
}

impl Default for WorldSmoothing {
    fn default() -> Self {
        WorldSmoothing::new()
    }
}

impl WorldSmoothing {
    /// Filters with no history.
    pub fn new() -> WorldSmoothing {
        WorldSmoothing {
            params: OneEuroParams::WORLD_OUTPUT,
            place: [Vec3::ZERO; NUM_LANDMARKS],
            speed: [Vec3::ZERO; NUM_LANDMARKS],
            last_secs: None,
        }
    }

    /// Forgets the history (the person was lost).
    pub fn reset(&mut self) {
        self.last_secs = None;
    }

    /// The landmarks' labels were exchanged between frames (see
    /// [`super::LandmarkStages`]): each history moves to the landmark that now names its
    /// point, its depth mirrored as the reading's is.
    pub fn exchange_sides(&mut self) {
        for &(l, r) in &LR_PAIRS {
            self.place.swap(l, r);
            self.speed.swap(l, r);
        }
        for p in self.place.iter_mut().chain(self.speed.iter_mut()) {
            p.z = -p.z;
        }
    }

    /// Takes `lm`'s reading (about `centre`) whole as the history, at rest.
    fn start(&mut self, lm: &Landmarks, centre: Vec3, time_secs: f64) {
        for (place, w) in self.place.iter_mut().zip(&lm.world) {
            let p = *w - centre;
            *place = if p.is_finite() { p } else { Vec3::ZERO };
        }
        self.speed = [Vec3::ZERO; NUM_LANDMARKS];
        self.last_secs = Some(time_secs);
    }

    /// Smooths `lm`'s body world landmarks (camera axes, metres) observed at `time_secs`.
    pub fn apply(&mut self, lm: &mut Landmarks, time_secs: f64) {
        let centre = seen_torso_middle(lm);
        if !centre.is_finite() {
            return;
        }
        let hips = hip_centre(lm);
        let dt = match self.last_secs.map(|last| (time_secs - last) as f32) {
            Some(dt) if dt > 0.0 => dt,
            // The same instant again: nothing to smooth over.
            Some(0.0) => return,
            // The first frame, or time went back (a replay restarted): taken whole.
            _ => {
                self.start(lm, centre, time_secs);
                return;
            }
        };
        self.last_secs = Some(time_secs);
        // Each point's speed, then the body's: the mean of their sizes, each by how well
        // the point is seen.
        let a_d = alpha(self.params.d_cutoff, dt);
        let (mut sum, mut weight) = (0.0, 0.0);
        for i in 0..NUM_LANDMARKS {
            let w = seen(lm, i);
            if w > 0.0 {
                let moved = (lm.world[i] - centre - self.place[i]) / dt;
                self.speed[i] += (moved - self.speed[i]) * (a_d * w);
                sum += self.speed[i].length() * w;
                weight += w;
            }
        }
        let body_speed = if weight > 1e-6 { sum / weight } else { 0.0 };
        let a = alpha(self.params.min_cutoff + self.params.beta * body_speed, dt);
        for i in 0..NUM_LANDMARKS {
            let w = seen(lm, i);
            if w > 0.0 {
                self.place[i] += (lm.world[i] - centre - self.place[i]) * (a * w);
            }
            lm.world[i] = centre + self.place[i];
        }
        // The hips' centre stays where the reading put it.
        let moved = hip_centre(lm) - hips;
        for w in lm.world.iter_mut() {
            *w -= moved;
        }
    }
}

/// How far a reading of landmark `i` is believed: its visibility, nothing when it is not a
/// number.
fn seen(lm: &Landmarks, i: usize) -> f32 {
    let v = lm.visibility(i);
    if v.is_finite() && lm.world[i].is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn hip_centre(lm: &Landmarks) -> Vec3 {
    (lm.world[idx::LEFT_HIP] + lm.world[idx::RIGHT_HIP]) * 0.5
}

/// The torso's corners averaged by how well each is seen (all alike when none is).
fn seen_torso_middle(lm: &Landmarks) -> Vec3 {
    let weight: f32 = TORSO.iter().map(|&i| lm.visibility(i).max(0.0)).sum();
    if weight > 1e-6 {
        TORSO
            .iter()
            .map(|&i| lm.world[i] * lm.visibility(i).max(0.0))
            .sum::<Vec3>()
            / weight
    } else {
        TORSO.iter().map(|&i| lm.world[i]).sum::<Vec3>() / TORSO.len() as f32
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// A still, fully seen body (hips at the origin, shoulders above, arms out).
    fn body() -> Landmarks {
        let mut lm = Landmarks::default();
        for (i, (w, p)) in lm.world.iter_mut().zip(lm.image.iter_mut()).enumerate() {
            let t = i as f32;
            *w = Vec3::new(
                0.3 * (t * 1.3).sin(),
                -0.6 * (t * 0.7).cos().abs(),
                0.1 * t.cos(),
            );
            *p = Vec4::new(0.0, 0.0, 0.0, 1.0);
        }
        lm.world[idx::LEFT_HIP] = Vec3::new(0.1, 0.0, 0.01);
        lm.world[idx::RIGHT_HIP] = Vec3::new(-0.1, 0.0, -0.01);
        lm.world[idx::LEFT_SHOULDER] = Vec3::new(0.18, -0.5, 0.0);
        lm.world[idx::RIGHT_SHOULDER] = Vec3::new(-0.18, -0.5, 0.0);
        lm
    }

    /// The mean frame-to-frame acceleration (metres a frame²) of `point` about the
    /// shoulders' middle over `frames`.
    fn jitter(frames: &[Landmarks], point: usize) -> f32 {
        let at = |lm: &Landmarks| {
            lm.world[point] - (lm.world[idx::LEFT_SHOULDER] + lm.world[idx::RIGHT_SHOULDER]) * 0.5
        };
        let acc: Vec<f32> = frames
            .windows(3)
            .map(|w| (at(&w[0]) - 2.0 * at(&w[1]) + at(&w[2])).length())
            .collect();
        acc.iter().sum::<f32>() / acc.len() as f32
    }

    /// Sixty frames at 30 fps of `body` with the hips (hidden) and the left wrist jittering by
    /// `noise` metres, the wrist seen at `wrist_seen`: the frames before and after the stage.
    fn run(noise: f32, wrist_seen: f32) -> (Vec<Landmarks>, Vec<Landmarks>) {
        let mut stage = WorldSmoothing::new();
        let (mut before, mut after) = (Vec::new(), Vec::new());
        for i in 0..60 {
            let mut lm = body();
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let wobble = Vec3::new(sign * noise, -sign * noise, sign * noise);
            // Hidden hips guessed about, and the output drawn around their centre.
            for h in [idx::LEFT_HIP, idx::RIGHT_HIP] {
                lm.image[h].w = 0.1;
            }
            for w in lm.world.iter_mut() {
                *w -= wobble;
            }
            lm.world[idx::LEFT_WRIST] += wobble * 2.0;
            lm.image[idx::LEFT_WRIST].w = wrist_seen;
            before.push(lm);
            stage.apply(&mut lm, i as f64 / 30.0);
            after.push(lm);
        }
        (before, after)
    }

    #[test]
    fn a_still_body_passes_unchanged_and_stays_centred_on_its_hips() {
        let mut stage = WorldSmoothing::new();
        for i in 0..30 {
            let mut lm = body();
            stage.apply(&mut lm, i as f64 / 30.0);
            for (got, want) in lm.world.iter().zip(body().world.iter()) {
                assert!(got.abs_diff_eq(*want, 1e-5), "{got} against {want}");
            }
        }
    }

    #[test]
    fn jitter_about_the_seen_torso_is_smoothed_and_a_guessed_hip_centre_is_not_read_as_speed() {
        let (before, after) = run(0.004, 1.0);
        let (raw, smoothed) = (
            jitter(&before, idx::LEFT_WRIST),
            jitter(&after, idx::LEFT_WRIST),
        );
        assert!(smoothed < 0.5 * raw, "{raw} -> {smoothed}");
        // Guessed unseen, the same wrist's jumps count for less still.
        let (_, faint) = run(0.004, 0.05);
        let faint = jitter(&faint, idx::LEFT_WRIST);
        assert!(faint < 0.5 * smoothed, "{smoothed} -> {faint}");
        // The elbow, still about the shoulders, stays still though the hips' centre jitters.
        assert!(jitter(&after, idx::LEFT_ELBOW) < 1e-4);
        // The output is still centred where the reading's hips are.
        for (a, b) in after.iter().zip(&before) {
            assert!(hip_centre(a).abs_diff_eq(hip_centre(b), 1e-5));
        }
    }

    #[test]
    fn an_unseen_point_is_held_and_a_seen_one_followed() {
        let wrist = |frames: &[Landmarks]| {
            let lm = frames.last().unwrap();
            lm.world[idx::LEFT_WRIST]
                - (lm.world[idx::LEFT_SHOULDER] + lm.world[idx::RIGHT_SHOULDER]) * 0.5
        };
        let rest = wrist(&[body()]);
        // A wrist 20 cm off from the first frame on, the body still: seen, it is followed
        // there within a third of a second; hidden, it has barely left where it was first
        // read.
        let mut seen = WorldSmoothing::new();
        let mut hidden = WorldSmoothing::new();
        let (mut a, mut b) = (body(), body());
        seen.apply(&mut a, 0.0);
        hidden.apply(&mut b, 0.0);
        for i in 1..=10 {
            a = body();
            b = body();
            a.world[idx::LEFT_WRIST].y += 0.2;
            b.world[idx::LEFT_WRIST].y += 0.2;
            b.image[idx::LEFT_WRIST].w = 0.02;
            seen.apply(&mut a, i as f64 / 30.0);
            hidden.apply(&mut b, i as f64 / 30.0);
        }
        assert!(
            (wrist(&[a]).y - rest.y - 0.2).abs() < 0.01,
            "{}",
            wrist(&[a])
        );
        assert!((wrist(&[b]).y - rest.y).abs() < 0.01, "{}", wrist(&[b]));
    }

    #[test]
    fn exchanged_sides_carry_their_histories() {
        let mut stage = WorldSmoothing::new();
        let mut lm = body();
        stage.apply(&mut lm, 0.0);
        let mut mirrored = body();
        crate::vision::sides::flip_interpretation(&mut mirrored);
        stage.exchange_sides();
        let want = mirrored;
        stage.apply(&mut mirrored, 1.0 / 30.0);
        for i in [idx::LEFT_ELBOW, idx::RIGHT_WRIST, idx::LEFT_KNEE] {
            assert!(
                mirrored.world[i].abs_diff_eq(want.world[i], 0.01),
                "{i}: {} against {}",
                mirrored.world[i],
                want.world[i]
            );
        }
    }

    #[test]
    fn no_number_from_nothing_and_a_bad_point_spoils_no_other() {
        let mut stage = WorldSmoothing::new();
        let mut lm = Landmarks::default();
        stage.apply(&mut lm, 0.0);
        stage.apply(&mut lm, 0.1);
        assert!(lm.world.iter().all(|w| w.is_finite()));
        // A wrist read as not a number, from the first frame on or later: every other point
        // stays a number.
        for first_bad in [0, 3] {
            let mut stage = WorldSmoothing::new();
            for i in 0..8 {
                let mut lm = body();
                lm.world[idx::LEFT_ELBOW].x += 0.01 * i as f32;
                if i >= first_bad {
                    lm.world[idx::LEFT_WRIST] = Vec3::NAN;
                }
                stage.apply(&mut lm, i as f64 / 30.0);
                let fine = lm
                    .world
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != idx::LEFT_WRIST)
                    .all(|(_, w)| w.is_finite());
                assert!(fine, "frame {i}");
            }
        }
    }

    #[test]
    fn time_going_back_starts_afresh() {
        let mut stage = WorldSmoothing::new();
        for i in 0..10 {
            stage.apply(&mut body(), i as f64 / 30.0);
        }
        // A replay restarted: its first frame is taken as it is, not drawn towards the old.
        let mut moved = body();
        moved.world[idx::LEFT_WRIST].y += 0.3;
        let want = moved;
        stage.apply(&mut moved, 0.0);
        assert!(moved.world[idx::LEFT_WRIST].abs_diff_eq(want.world[idx::LEFT_WRIST], 1e-5));
    }
}
