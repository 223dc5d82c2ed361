//! The blend of a lock switching on or off, as an offset that decays with a critically damped
//! spring (inertialization): at a switch the offset takes up the difference between where the
//! foot was shown and where it should now go, in position and in velocity, so the foot neither
//! jumps nor stops dead; then it decays to zero within a few half-lives.

use glam::Vec3;

/// Offsets below this are zero (decaying offsets must not become subnormal floats, which
/// makes the arithmetic slow).
const NEGLIGIBLE: f32 = 1e-6;

/// A decaying offset of one quantity (`Vec3` positions or `f32` angles).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Decay<T> {
    /// The offset.
    pub value: T,
    /// Its rate of change per second.
    pub velocity: T,
}

/// Arithmetic the spring needs.
pub trait Offset: Copy + Default {
    /// `self + other * k`.
    fn add_scaled(self, other: Self, k: f32) -> Self;
    /// Size (for the negligible test).
    fn size(self) -> f32;
}

impl Offset for Vec3 {
    fn add_scaled(self, other: Self, k: f32) -> Self {
        self + other * k
    }
    fn size(self) -> f32 {
        self.length()
    }
}

impl Offset for f32 {
    fn add_scaled(self, other: Self, k: f32) -> Self {
        self + other * k
    }
    fn size(self) -> f32 {
        self.abs()
    }
}

impl<T: Offset> Decay<T> {
    /// Advances the spring by `dt_secs` with the given half-life.
    pub fn step(&mut self, dt_secs: f32, halflife_secs: f32) {
        if dt_secs <= 0.0 {
            return;
        }
        let y = 2.0 * std::f32::consts::LN_2 / halflife_secs.max(1e-4);
        let j1 = self.velocity.add_scaled(self.value, y);
        let decay = (-y * dt_secs).exp();
        self.value = self.value.add_scaled(j1, dt_secs);
        self.value = T::default().add_scaled(self.value, decay);
        self.velocity = self.velocity.add_scaled(j1, -y * dt_secs);
        self.velocity = T::default().add_scaled(self.velocity, decay);
        if self.value.size() < NEGLIGIBLE && self.velocity.size() < NEGLIGIBLE {
            *self = Decay::default();
        }
    }

    /// True while the offset still shows.
    pub fn is_active(&self) -> bool {
        self.value.size() >= NEGLIGIBLE || self.velocity.size() >= NEGLIGIBLE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_decays_smoothly_to_zero() {
        let mut d = Decay {
            value: 1.0f32,
            velocity: 0.0,
        };
        let mut last = d.value;
        for _ in 0..60 {
            d.step(1.0 / 60.0, 0.05);
            assert!(d.value <= last + 1e-6 && d.value >= -1e-3, "{d:?}");
            last = d.value;
        }
        assert!(d.value.abs() < 1e-3);
        // One half-life of a resting offset leaves less than the offset (critically damped
        // springs lag a plain exponential a little), and a lot more than nothing.
        let mut d = Decay {
            value: 1.0f32,
            velocity: 0.0,
        };
        for _ in 0..6 {
            d.step(0.1 / 6.0, 0.1);
        }
        assert!(d.value > 0.5 && d.value < 0.95, "{d:?}");
    }

    #[test]
    fn a_moving_start_keeps_its_velocity_then_returns() {
        let mut d = Decay {
            value: Vec3::ZERO,
            velocity: Vec3::X,
        };
        d.step(1.0 / 120.0, 0.05);
        assert!(d.value.x > 0.0 && d.value.x < 1.0 / 120.0 + 1e-6);
        for _ in 0..120 {
            d.step(1.0 / 120.0, 0.05);
        }
        assert!(!d.is_active() || d.value.length() < 1e-4);
    }
}
