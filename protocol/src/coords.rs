//! Coordinate conversions between the internal space and external tools' spaces.
//!
//! * Internal: right-handed, +Y up, metres (same as glTF).
//! * Unity / VMC: left-handed, +Y up, +Z forward, metres. Characters face +Z in both spaces
//!   (glTF and VRM/Unity avatars alike), so the two differ by a mirror of the **X** axis (the
//!   convention UniVRM uses between glTF and Unity): positions map `(x, y, z) → (-x, y, z)`. A
//!   rotation `R` becomes `M R M` (M = diag(-1, 1, 1)): the mirrored axis with the opposite
//!   angle, which in quaternion form is `(x, -y, -z, w)`. Mirroring Z instead would turn every
//!   character around, and since receivers apply the *local* rotations to their own +Z-facing
//!   bones, that flips how every joint bends (knees forward), not only where the root faces.
//! * Blender: right-handed, +Z up, metres. The two differ by a proper rotation of +90° about X
//!   (internal +Y → Blender +Z, internal +Z → Blender -Y), the same mapping Blender's glTF
//!   importer uses, so a character facing internal +Z faces Blender's front (-Y). Positions map
//!   `(x, y, z) → (x, -z, y)` and a quaternion's vector part maps the same way, `w` unchanged.
//!   Blender's `mathutils.Quaternion` takes `(w, x, y, z)`: see [`blender_wxyz`].
//!
//! Each conversion has one function per direction, proven by round-trip tests and by tests
//! against independently computed rotations.

use glam::{Quat, Vec3};

/// Internal position → Unity position (`(-x, y, z)`).
#[inline]
pub fn unity_from_internal_position(p: Vec3) -> Vec3 {
    Vec3::new(-p.x, p.y, p.z)
}

/// Unity position → internal position (the mirror is its own inverse).
#[inline]
pub fn internal_from_unity_position(p: Vec3) -> Vec3 {
    Vec3::new(-p.x, p.y, p.z)
}

/// Internal rotation → Unity rotation (`(x, -y, -z, w)`).
#[inline]
pub fn unity_from_internal_rotation(q: Quat) -> Quat {
    Quat::from_xyzw(q.x, -q.y, -q.z, q.w)
}

/// Unity rotation → internal rotation (the mirror is its own inverse).
#[inline]
pub fn internal_from_unity_rotation(q: Quat) -> Quat {
    Quat::from_xyzw(q.x, -q.y, -q.z, q.w)
}

/// Internal position → Blender position.
#[inline]
pub fn blender_from_internal_position(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.z, p.y)
}

/// Blender position → internal position.
#[inline]
pub fn internal_from_blender_position(p: Vec3) -> Vec3 {
    Vec3::new(p.x, p.z, -p.y)
}

/// Internal rotation → Blender rotation (a glam quaternion in Blender's axes).
#[inline]
pub fn blender_from_internal_rotation(q: Quat) -> Quat {
    Quat::from_xyzw(q.x, -q.z, q.y, q.w)
}

/// Blender rotation → internal rotation.
#[inline]
pub fn internal_from_blender_rotation(q: Quat) -> Quat {
    Quat::from_xyzw(q.x, q.z, -q.y, q.w)
}

/// A quaternion in `mathutils.Quaternion` component order `(w, x, y, z)`.
#[inline]
pub fn blender_wxyz(q: Quat) -> [f32; 4] {
    [q.w, q.x, q.y, q.z]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_2;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    fn sample_rotations() -> Vec<Quat> {
        vec![
            Quat::IDENTITY,
            Quat::from_rotation_x(FRAC_PI_2),
            Quat::from_rotation_y(0.7),
            Quat::from_rotation_z(-1.3),
            Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize_or_zero(), 2.2),
        ]
    }

    fn sample_points() -> Vec<Vec3> {
        vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.3, -1.2, 2.5)]
    }

    /// Rotating a sample point in our space then converting it equals converting it then
    /// rotating it by the converted rotation, for every sample rotation.
    fn assert_rotation_commutes(position: fn(Vec3) -> Vec3, rotation: fn(Quat) -> Quat) {
        for q in sample_rotations() {
            let converted = rotation(q);
            for p in sample_points() {
                let ours_then_converted = position(q * p);
                let converted_then_rotated = converted * position(p);
                assert!(
                    close(ours_then_converted, converted_then_rotated),
                    "{q:?} {p:?}"
                );
            }
        }
    }

    /// `back(to(p)) == p` for every sample point.
    fn assert_points_round_trip(to: fn(Vec3) -> Vec3, back: fn(Vec3) -> Vec3) {
        for p in sample_points() {
            assert_eq!(back(to(p)), p);
        }
    }

    #[test]
    fn unity_round_trip() {
        for q in sample_rotations() {
            assert_eq!(
                internal_from_unity_rotation(unity_from_internal_rotation(q)),
                q
            );
        }
        assert_points_round_trip(unity_from_internal_position, internal_from_unity_position);
    }

    #[test]
    fn blender_round_trip() {
        for q in sample_rotations() {
            let back = internal_from_blender_rotation(blender_from_internal_rotation(q));
            assert!((back - q).length() < 1e-7);
        }
        assert_points_round_trip(
            blender_from_internal_position,
            internal_from_blender_position,
        );
    }

    /// Rotating in our space then mirroring must equal mirroring then rotating in Unity space.
    /// Unity's rotation is applied with the same quaternion formula (`q v q*`): what differs
    /// between the engines is only the handedness of the axes the numbers refer to.
    #[test]
    fn unity_rotation_commutes_with_mirror() {
        assert_rotation_commutes(unity_from_internal_position, unity_from_internal_rotation);
    }

    /// Known cases worked by hand (Unity applies `q v q*` with the same formula; only the
    /// handedness of the axes differs). +90° about +X takes +Y to +Z in ours; neither axis is
    /// mirrored, so the Unity quaternion is the same and does the same. +90° about +Y takes
    /// forward (+Z) to +X in ours; ours +X is Unity −X, so in Unity it must take +Z to −X.
    #[test]
    fn known_rotations_map_to_expected_unity_rotations() {
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let pitch = unity_from_internal_rotation(Quat::from_rotation_x(FRAC_PI_2));
        assert!(pitch.dot(Quat::from_xyzw(s, 0.0, 0.0, s)).abs() > 1.0 - 1e-6);
        assert!(close(pitch * Vec3::Y, Vec3::Z));
        let yaw = unity_from_internal_rotation(Quat::from_rotation_y(FRAC_PI_2));
        assert!(close(yaw * Vec3::Z, -Vec3::X));
        // A character facing internal +Z faces Unity +Z: forward is not mirrored.
        assert_eq!(unity_from_internal_position(Vec3::Z), Vec3::Z);
        assert_eq!(unity_from_internal_position(Vec3::X), -Vec3::X);
    }

    #[test]
    fn blender_axes_are_as_documented() {
        assert_eq!(blender_from_internal_position(Vec3::Y), Vec3::Z);
        assert_eq!(blender_from_internal_position(Vec3::Z), -Vec3::Y);
        assert_eq!(blender_from_internal_position(Vec3::X), Vec3::X);
        // Rotating then converting equals converting then rotating (a proper rotation of axes).
        assert_rotation_commutes(
            blender_from_internal_position,
            blender_from_internal_rotation,
        );
        // +90° about internal +Y (up) is +90° about Blender +Z (up).
        let up = blender_from_internal_rotation(Quat::from_rotation_y(FRAC_PI_2));
        assert!(up.dot(Quat::from_rotation_z(FRAC_PI_2)).abs() > 1.0 - 1e-6);
        assert_eq!(
            blender_wxyz(Quat::from_xyzw(1.0, 2.0, 3.0, 4.0)),
            [4.0, 1.0, 2.0, 3.0]
        );
    }
}
