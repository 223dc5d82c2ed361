//! Euler ↔ quaternion helpers for every Tait–Bryan rotation order.
//!
//! Convention (BVH's): an order such as `ZXY` means the rotation matrix is `Rz · Rx · Ry`: the
//! channels are applied in the listed order to the child's frame (intrinsic rotations).

use glam::{EulerRot, Quat};
use serde::{Deserialize, Serialize};

/// The order in which three axis rotations compose; `Zxy` means `R = Rz · Rx · Ry`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum RotationOrder {
    /// R = Rx · Ry · Rz
    Xyz,
    /// R = Rx · Rz · Ry
    Xzy,
    /// R = Ry · Rx · Rz
    Yxz,
    /// R = Ry · Rz · Rx
    Yzx,
    /// R = Rz · Rx · Ry
    Zxy,
    /// R = Rz · Ry · Rx
    Zyx,
}

impl RotationOrder {
    /// All six orders.
    pub const ALL: [RotationOrder; 6] = [
        RotationOrder::Xyz,
        RotationOrder::Xzy,
        RotationOrder::Yxz,
        RotationOrder::Yzx,
        RotationOrder::Zxy,
        RotationOrder::Zyx,
    ];

    /// Parses three axis letters such as `"ZXY"` (case-insensitive).
    pub fn from_axes(axes: &str) -> Option<RotationOrder> {
        match axes.to_ascii_uppercase().as_str() {
            "XYZ" => Some(RotationOrder::Xyz),
            "XZY" => Some(RotationOrder::Xzy),
            "YXZ" => Some(RotationOrder::Yxz),
            "YZX" => Some(RotationOrder::Yzx),
            "ZXY" => Some(RotationOrder::Zxy),
            "ZYX" => Some(RotationOrder::Zyx),
            _ => None,
        }
    }

    /// The three axis letters, e.g. `"ZXY"`.
    pub fn axes(self) -> &'static str {
        match self {
            RotationOrder::Xyz => "XYZ",
            RotationOrder::Xzy => "XZY",
            RotationOrder::Yxz => "YXZ",
            RotationOrder::Yzx => "YZX",
            RotationOrder::Zxy => "ZXY",
            RotationOrder::Zyx => "ZYX",
        }
    }

    /// glam's intrinsic variant with the same meaning.
    fn glam(self) -> EulerRot {
        match self {
            RotationOrder::Xyz => EulerRot::XYZ,
            RotationOrder::Xzy => EulerRot::XZY,
            RotationOrder::Yxz => EulerRot::YXZ,
            RotationOrder::Yzx => EulerRot::YZX,
            RotationOrder::Zxy => EulerRot::ZXY,
            RotationOrder::Zyx => EulerRot::ZYX,
        }
    }

    /// Rotation from three angles in radians, given in this order's axis order
    /// (for `Zxy`: `[z, x, y]`).
    pub fn to_quat(self, angles_rad: [f32; 3]) -> Quat {
        Quat::from_euler(self.glam(), angles_rad[0], angles_rad[1], angles_rad[2])
    }

    /// Angles in radians, in this order's axis order, that reproduce `q` via [`Self::to_quat`].
    /// Decomposed in f64 so that angles near gimbal lock keep BVH's precision; at gimbal lock
    /// the last angle is set to zero.
    pub fn from_quat(self, q: Quat) -> [f32; 3] {
        let (i, j, k) = self.axis_indices();
        let m = rotation_matrix_f64(q);
        // Even permutations (XYZ, YZX, ZXY) and odd ones differ only in signs.
        let cyclic = matches!(
            self,
            RotationOrder::Xyz | RotationOrder::Yzx | RotationOrder::Zxy
        );
        let s = if cyclic { 1.0 } else { -1.0 };
        let sin_b = (s * m[i][k]).clamp(-1.0, 1.0);
        let b = sin_b.asin();
        let (a, c);
        if sin_b.abs() < 1.0 - 1e-9 {
            a = (-s * m[j][k]).atan2(m[k][k]);
            c = (-s * m[i][j]).atan2(m[i][i]);
        } else {
            // Gimbal lock: only a ± c is defined; put it all in a.
            a = (s * m[k][j]).atan2(m[j][j]);
            c = 0.0;
        }
        [a as f32, b as f32, c as f32]
    }

    fn axis_indices(self) -> (usize, usize, usize) {
        match self {
            RotationOrder::Xyz => (0, 1, 2),
            RotationOrder::Xzy => (0, 2, 1),
            RotationOrder::Yxz => (1, 0, 2),
            RotationOrder::Yzx => (1, 2, 0),
            RotationOrder::Zxy => (2, 0, 1),
            RotationOrder::Zyx => (2, 1, 0),
        }
    }
}

/// Row-major 3×3 rotation matrix of a (normalised) quaternion, in f64.
fn rotation_matrix_f64(q: Quat) -> [[f64; 3]; 3] {
    let (x, y, z, w) = (q.x as f64, q.y as f64, q.z as f64, q.w as f64);
    let n = (x * x + y * y + z * z + w * w).sqrt().max(1e-300);
    let (x, y, z, w) = (x / n, y / n, z / n, w / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::quat_close;
    use glam::Vec3;

    #[test]
    fn order_means_listed_product() {
        let (a, b, c) = (0.3f32, -0.7f32, 1.1f32);
        let rx = |t| Quat::from_axis_angle(Vec3::X, t);
        let ry = |t| Quat::from_axis_angle(Vec3::Y, t);
        let rz = |t| Quat::from_axis_angle(Vec3::Z, t);
        let expect = [
            (RotationOrder::Xyz, rx(a) * ry(b) * rz(c)),
            (RotationOrder::Xzy, rx(a) * rz(b) * ry(c)),
            (RotationOrder::Yxz, ry(a) * rx(b) * rz(c)),
            (RotationOrder::Yzx, ry(a) * rz(b) * rx(c)),
            (RotationOrder::Zxy, rz(a) * rx(b) * ry(c)),
            (RotationOrder::Zyx, rz(a) * ry(b) * rx(c)),
        ];
        for (order, q) in expect {
            assert!(quat_close(order.to_quat([a, b, c]), q, 1e-5), "{order:?}");
        }
    }

    #[test]
    fn round_trip_every_order() {
        let samples = [
            [0.1f32, 0.2, 0.3],
            [-2.0, 0.5, 3.0],
            [1.2, -1.4, -0.2],
            [0.0, 0.0, 0.0],
            [3.0, 1.5, -3.0],
            [0.4, std::f32::consts::FRAC_PI_2, 0.0],
            [0.4, -std::f32::consts::FRAC_PI_2, 0.0],
            [0.7, std::f32::consts::FRAC_PI_2 - 1e-4, 0.2],
        ];
        for order in RotationOrder::ALL {
            assert_eq!(RotationOrder::from_axes(order.axes()), Some(order));
            for s in samples {
                let q = order.to_quat(s);
                let back = order.to_quat(order.from_quat(q));
                assert!(quat_close(q, back, 2e-3), "{order:?} {s:?}");
            }
        }
        assert_eq!(RotationOrder::from_axes("XXY"), None);
    }
}
