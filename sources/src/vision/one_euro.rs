//! One Euro filter (Casiez, Roussel, Vogel 2012): a low-pass filter whose cutoff rises with
//! speed, so slow motion is smoothed hard (no jitter) and fast motion lags little.
//!
//! cutoff = min_cutoff + beta · |filtered derivative|; α = 1 / (1 + τ/dt) with τ = 1/(2π·cutoff).

use std::f32::consts::TAU;

/// Filter parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneEuroParams {
    /// Cutoff at rest, Hz.
    pub min_cutoff: f32,
    /// Cutoff increase per unit/second of speed.
    pub beta: f32,
    /// Cutoff for the derivative, Hz.
    pub d_cutoff: f32,
}

impl OneEuroParams {
    /// Defaults for world landmarks in metres: min_cutoff 1 Hz, beta 0.007 per mm/s (= 7 per
    /// m/s), d_cutoff 1 Hz.
    pub const METRES: OneEuroParams = OneEuroParams {
        min_cutoff: 1.0,
        beta: 7.0,
        d_cutoff: 1.0,
    };
    /// For world landmarks already in the camera's axes, as MediaPipe's pose graph smooths its
    /// own world landmarks (metres, no scaling by the body's size): min_cutoff 0.1 Hz, beta 40
    /// per m/s, d_cutoff 1 Hz. Heavy at rest, near pass-through for a limb in motion.
    pub const WORLD_OUTPUT: OneEuroParams = OneEuroParams {
        min_cutoff: 0.1,
        beta: 40.0,
        d_cutoff: 1.0,
    };
    /// Defaults for image landmarks in pixels (a person spans roughly a thousand pixels, so a
    /// pixel is about a millimetre).
    pub const PIXELS: OneEuroParams = OneEuroParams {
        min_cutoff: 1.0,
        beta: 0.007,
        d_cutoff: 1.0,
    };
}

/// The share of the way from the last output to a new reading that a low-pass filter with
/// `cutoff` (Hz) moves over `dt` seconds.
#[inline]
pub(super) fn alpha(cutoff: f32, dt: f32) -> f32 {
    let tau = 1.0 / (TAU * cutoff.max(1e-6));
    1.0 / (1.0 + tau / dt)
}

/// One scalar One Euro filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneEuro {
    params: OneEuroParams,
    state: Option<(f32, f32, f64)>, // (filtered value, filtered derivative, time)
}

impl OneEuro {
    /// A filter with no history.
    pub fn new(params: OneEuroParams) -> OneEuro {
        OneEuro {
            params,
            state: None,
        }
    }

    /// Forgets the history (after a tracking loss).
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Continues with the negated signal: the history's value and speed change sign (a
    /// coordinate mirrored between two frames carries on smoothly from its mirror image).
    pub fn negate(&mut self) {
        if let Some((x, dx, t)) = self.state {
            self.state = Some((-x, -dx, t));
        }
    }

    /// Filters `x` observed at `time_secs`. A non-increasing time returns the last value.
    pub fn filter(&mut self, x: f32, time_secs: f64) -> f32 {
        let Some((prev, dprev, tprev)) = self.state else {
            self.state = Some((x, 0.0, time_secs));
            return x;
        };
        let dt = (time_secs - tprev) as f32;
        if dt.is_nan() || dt <= 0.0 || !x.is_finite() {
            return prev;
        }
        let dx = (x - prev) / dt;
        let a_d = alpha(self.params.d_cutoff, dt);
        let dhat = dprev + a_d * (dx - dprev);
        let cutoff = self.params.min_cutoff + self.params.beta * dhat.abs();
        let a = alpha(cutoff, dt);
        let xhat = prev + a * (x - prev);
        self.state = Some((xhat, dhat, time_secs));
        xhat
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn constant_input_passes_unchanged() {
        let mut f = OneEuro::new(OneEuroParams::METRES);
        for i in 0..50 {
            assert!((f.filter(0.25, i as f64 / 60.0) - 0.25).abs() < 1e-6);
        }
    }

    #[test]
    fn jitter_is_reduced_and_fast_motion_is_followed() {
        let params = OneEuroParams::METRES;
        // Alternating ±5 mm noise around a still point: output spread shrinks a lot.
        let mut f = OneEuro::new(params);
        let mut spread: f32 = 0.0;
        for i in 0..120 {
            let noise = if i % 2 == 0 { 0.005 } else { -0.005 };
            let y = f.filter(noise, i as f64 / 60.0);
            if i > 30 {
                spread = spread.max(y.abs());
            }
        }
        assert!(spread < 0.0025, "spread {spread}");
        // A 2 m/s ramp: the lag after half a second stays small (beta raises the cutoff).
        let mut f = OneEuro::new(params);
        let mut y = 0.0;
        for i in 0..30 {
            y = f.filter(2.0 * i as f32 / 60.0, i as f64 / 60.0);
        }
        let truth = 2.0 * 29.0 / 60.0;
        assert!((truth - y).abs() < 0.05, "lag {}", truth - y);
    }

    #[test]
    fn reset_and_bad_time_are_safe() {
        let mut f = OneEuro::new(OneEuroParams::PIXELS);
        f.filter(10.0, 1.0);
        assert_eq!(f.filter(99.0, 1.0), 10.0);
        assert_eq!(f.filter(f32::NAN, 2.0), 10.0);
        f.reset();
        assert_eq!(f.filter(99.0, 3.0), 99.0);
    }
}
