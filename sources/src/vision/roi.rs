//! Regions of interest: the rotated square crops the landmark model sees.
//!
//! A [`Roi`] maps the model's 256×256 crop to the frame: crop point (nx, ny) ∈ [-½, ½]² goes to
//! `centre + size · R(rotation) · (nx, ny)` in frame pixels (y down). Tracking derives the next
//! ROI from the auxiliary landmarks 33 (hip centre) and 34 (above the head), as MediaPipe does:
//! rotated so that the 33→34 line points up in the crop, and 2 × 1.25 × |33→34| wide.

use glam::Vec2;

/// MediaPipe's ROI scale around the aligned person (2 × the centre→scale distance, × 1.25).
const ROI_SCALE: f32 = 2.5;

/// A rotated square crop in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roi {
    /// Centre, pixels.
    pub center: Vec2,
    /// Side length, pixels.
    pub size: f32,
    /// Rotation, radians (crop → frame, clockwise on screen since y points down).
    pub rotation: f32,
}

impl Roi {
    /// An upright square.
    pub fn square(center: Vec2, size: f32) -> Roi {
        Roi {
            center,
            size,
            rotation: 0.0,
        }
    }

    /// Maps normalised crop coordinates (each in [-½, ½]) to frame pixels.
    #[inline]
    pub fn to_frame(&self, n: Vec2) -> Vec2 {
        let (s, c) = self.rotation.sin_cos();
        let v = n * self.size;
        self.center + Vec2::new(c * v.x - s * v.y, s * v.x + c * v.y)
    }

    /// Rotates a vector by the ROI's rotation (used for world landmarks).
    #[inline]
    pub fn rotate(&self, v: Vec2) -> Vec2 {
        let (s, c) = self.rotation.sin_cos();
        Vec2::new(c * v.x - s * v.y, s * v.x + c * v.y)
    }

    /// The ROI for the next frame from the auxiliary landmarks (frame pixels): centre at `center`,
    /// rotated so that `center → scale` points up. `None` when the points coincide or are not
    /// finite.
    pub fn from_alignment(center: Vec2, scale: Vec2) -> Option<Roi> {
        let d = scale - center;
        let len = d.length();
        if !(len.is_finite() && len > 1.0 && center.is_finite()) {
            return None;
        }
        Some(Roi {
            center,
            size: ROI_SCALE * len,
            rotation: d.x.atan2(-d.y),
        })
    }

    /// Candidate crops for finding a person with no previous frame: the whole frame letterboxed,
    /// the largest centred squares along the long side, and a coarse grid of smaller squares.
    /// Written into `out` (cleared first) so a caller can reuse the buffer.
    pub fn search_candidates(width: u32, height: u32, out: &mut Vec<Roi>) {
        out.clear();
        let (w, h) = (width as f32, height as f32);
        let long = w.max(h);
        let short = w.min(h);
        out.push(Roi::square(Vec2::new(w / 2.0, h / 2.0), long));
        // Squares of the short side's size sliding along the long side (start, middle, end).
        for t in [0.5, 0.0, 1.0] {
            let c = if w >= h {
                Vec2::new(short / 2.0 + t * (w - short), h / 2.0)
            } else {
                Vec2::new(w / 2.0, short / 2.0 + t * (h - short))
            };
            out.push(Roi::square(c, short));
        }
        // A 3×3 grid of squares 60% of the short side, for small or off-centre people.
        let side = short * 0.6;
        for j in 0..3 {
            for i in 0..3 {
                let cx = side / 2.0 + (w - side) * i as f32 / 2.0;
                let cy = side / 2.0 + (h - side) * j as f32 / 2.0;
                out.push(Roi::square(Vec2::new(cx, cy), side));
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn upright_alignment_gives_unrotated_roi() {
        let roi = Roi::from_alignment(Vec2::new(100.0, 200.0), Vec2::new(100.0, 100.0)).unwrap();
        assert!(roi.rotation.abs() < 1e-6);
        assert!((roi.size - 250.0).abs() < 1e-4);
        // The crop's top centre lies above the centre.
        let top = roi.to_frame(Vec2::new(0.0, -0.5));
        assert!((top - Vec2::new(100.0, 75.0)).length() < 1e-3);
    }

    #[test]
    fn tilted_alignment_maps_crop_up_to_the_alignment_direction() {
        // Person lying to the right: head towards +x.
        let c = Vec2::new(50.0, 50.0);
        let roi = Roi::from_alignment(c, Vec2::new(90.0, 50.0)).unwrap();
        let up_in_frame = roi.to_frame(Vec2::new(0.0, -0.5)) - c;
        let dir = up_in_frame.normalize_or_zero();
        assert!((dir - Vec2::X).length() < 1e-5, "{dir}");
    }

    #[test]
    fn degenerate_alignment_is_rejected() {
        assert!(Roi::from_alignment(Vec2::ZERO, Vec2::ZERO).is_none());
        assert!(Roi::from_alignment(Vec2::new(f32::NAN, 0.0), Vec2::ONE * 9.0).is_none());
    }

    #[test]
    fn candidates_cover_a_portrait_frame() {
        let mut c = Vec::new();
        Roi::search_candidates(1080, 1920, &mut c);
        assert_eq!(c.len(), 13);
        assert_eq!(c[0].size, 1920.0);
        // The sliding squares reach both ends of the long side.
        assert!(c
            .iter()
            .any(|r| (r.center.y - 540.0).abs() < 1e-3 && r.size == 1080.0));
        assert!(c
            .iter()
            .any(|r| (r.center.y - 1380.0).abs() < 1e-3 && r.size == 1080.0));
    }
}
