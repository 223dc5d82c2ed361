//! BlazePose landmarks: indices, the per-frame landmark record and its coordinate spaces.
//!
//! `image`: x, y in pixels of the input frame, z in the same pixel scale (smaller = nearer the
//! camera), w = visibility in [0, 1]. `world`: metres, hip-centred, in the model's camera-like
//! axes (x right in the image, y down, z away from the camera); [`world_to_internal`] turns a
//! point into rigcast's +Y-up right-handed space, where a performer facing the camera faces +Z
//! and their left hand is on +X.

use glam::{Vec2, Vec3, Vec4};

/// Number of body landmarks.
pub const NUM_LANDMARKS: usize = 33;
/// Body + auxiliary landmarks the model outputs (33..=34 give the next ROI).
pub const NUM_MODEL_LANDMARKS: usize = 39;

/// Landmark indices (odd = left side of the performer).
#[allow(missing_docs)]
pub mod idx {
    pub const NOSE: usize = 0;
    pub const LEFT_EYE: usize = 2;
    pub const RIGHT_EYE: usize = 5;
    pub const LEFT_EAR: usize = 7;
    pub const RIGHT_EAR: usize = 8;
    pub const MOUTH_LEFT: usize = 9;
    pub const MOUTH_RIGHT: usize = 10;
    pub const LEFT_SHOULDER: usize = 11;
    pub const RIGHT_SHOULDER: usize = 12;
    pub const LEFT_ELBOW: usize = 13;
    pub const RIGHT_ELBOW: usize = 14;
    pub const LEFT_WRIST: usize = 15;
    pub const RIGHT_WRIST: usize = 16;
    pub const LEFT_PINKY: usize = 17;
    pub const RIGHT_PINKY: usize = 18;
    pub const LEFT_INDEX: usize = 19;
    pub const RIGHT_INDEX: usize = 20;
    pub const LEFT_HIP: usize = 23;
    pub const RIGHT_HIP: usize = 24;
    pub const LEFT_KNEE: usize = 25;
    pub const RIGHT_KNEE: usize = 26;
    pub const LEFT_ANKLE: usize = 27;
    pub const RIGHT_ANKLE: usize = 28;
    pub const LEFT_HEEL: usize = 29;
    pub const RIGHT_HEEL: usize = 30;
    pub const LEFT_FOOT_INDEX: usize = 31;
    pub const RIGHT_FOOT_INDEX: usize = 32;
    /// Auxiliary: hip centre, the next ROI's centre.
    pub const AUX_CENTER: usize = 33;
    /// Auxiliary: a point above the head; its distance to the centre gives the ROI's scale.
    pub const AUX_SCALE: usize = 34;
}

/// Landmark names in model order (for JSON and debugging).
pub const LANDMARK_NAMES: [&str; NUM_LANDMARKS] = [
    "nose",
    "left_eye_inner",
    "left_eye",
    "left_eye_outer",
    "right_eye_inner",
    "right_eye",
    "right_eye_outer",
    "left_ear",
    "right_ear",
    "mouth_left",
    "mouth_right",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_pinky",
    "right_pinky",
    "left_index",
    "right_index",
    "left_thumb",
    "right_thumb",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
    "left_heel",
    "right_heel",
    "left_foot_index",
    "right_foot_index",
];

/// Landmarks of one person in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landmarks {
    /// Image landmarks (x, y, z pixels; w visibility), 33 body + 6 auxiliary.
    pub image: [Vec4; NUM_MODEL_LANDMARKS],
    /// World landmarks, metres, model axes (see [`world_to_internal`]).
    pub world: [Vec3; NUM_MODEL_LANDMARKS],
    /// Pose presence in [0, 1].
    pub presence: f32,
    /// Size in pixels of the picture the image landmarks are in (the source's), zero when
    /// unknown (landmarks recorded before it was kept): the perspective stage needs where the
    /// picture's centre is and how wide it is.
    pub picture: Vec2,
    /// How far the landmark model's heatmaps move each image landmark (pixels, zero where
    /// they do not): the output takes it ([`Self::take_refinement`]), the tracker never sees
    /// it, so who is followed where and which way round stays the regression head's reading.
    /// Not recorded: a recording holds the output's points.
    pub refined: [Vec2; NUM_MODEL_LANDMARKS],
}

impl Default for Landmarks {
    fn default() -> Self {
        Landmarks::ZERO
    }
}

impl Landmarks {
    /// All zero, presence 0.
    pub const ZERO: Landmarks = Landmarks {
        image: [Vec4::ZERO; NUM_MODEL_LANDMARKS],
        world: [Vec3::ZERO; NUM_MODEL_LANDMARKS],
        presence: 0.0,
        picture: Vec2::ZERO,
        refined: [Vec2::ZERO; NUM_MODEL_LANDMARKS],
    };

    /// Visibility of body landmark `i` in [0, 1].
    #[inline]
    pub fn visibility(&self, i: usize) -> f32 {
        self.image[i].w
    }

    /// World landmark `i` in rigcast's internal space (+Y up, performer facing +Z).
    #[inline]
    pub fn world_internal(&self, i: usize) -> Vec3 {
        world_to_internal(self.world[i])
    }

    /// Multiplies the image landmarks' x, y and z (all in pixels) and the picture's size by
    /// `k`: from the pixels of a scaled frame to those of the source.
    pub fn scale_image(&mut self, k: f32) {
        if k == 1.0 {
            return;
        }
        self.picture *= k;
        for p in self.image.iter_mut() {
            p.x *= k;
            p.y *= k;
            p.z *= k;
        }
        for d in self.refined.iter_mut() {
            *d *= k;
        }
    }

    /// Moves each image landmark by its heatmap refinement (see [`Self::refined`]), which is
    /// then spent (zero).
    pub fn take_refinement(&mut self) {
        for (p, d) in self.image.iter_mut().zip(self.refined.iter_mut()) {
            p.x += d.x;
            p.y += d.y;
            *d = Vec2::ZERO;
        }
    }
}

/// Model world axes (x right in the image, y down, z away from the camera) → internal space
/// (+Y up, right-handed). A half turn about X: both flips keep the handedness.
#[inline]
pub fn world_to_internal(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.y, -p.z)
}

/// Numerically safe logistic function (the model emits visibility and presence as logits).
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x.clamp(-40.0, 40.0)).exp())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn internal_axes_keep_handedness_and_put_left_on_plus_x() {
        // A performer facing the camera has their left shoulder on the image's right (+x) and
        // the head above the hips (−y in the image).
        let left = world_to_internal(Vec3::new(0.2, 0.0, 0.0));
        let head = world_to_internal(Vec3::new(0.0, -0.5, 0.0));
        let near = world_to_internal(Vec3::new(0.0, 0.0, -0.3));
        assert!(left.x > 0.0 && head.y > 0.0 && near.z > 0.0);
        // Determinant of the axis map is +1 (a rotation, not a mirror).
        let m = glam::Mat3::from_cols(
            world_to_internal(Vec3::X),
            world_to_internal(Vec3::Y),
            world_to_internal(Vec3::Z),
        );
        assert!((m.determinant() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn sigmoid_is_bounded_and_centred() {
        assert!((sigmoid(0.0) - 0.5).abs() < 1e-6);
        assert!(sigmoid(1000.0) <= 1.0 && sigmoid(-1000.0) >= 0.0);
        assert!(sigmoid(3.0) > 0.95);
    }
}
