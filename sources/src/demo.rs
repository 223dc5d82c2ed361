//! The embedded demo: a project-made humanoid walking in place, generated procedurally.
//!
//! ```text
//!                 head_top
//!                   head
//!                   neck
//!  hand_tip_r … clavicle_r ─ chest ─ clavicle_l … hand_tip_l
//!                spine_upper
//!                spine_lower
//!                  pelvis (root, bobbing)
//!          leg_upper_r   leg_upper_l
//!          leg_lower_r   leg_lower_l
//!          foot_r/toes_r foot_l/toes_l
//! ```
//!
//! 25 bones, T-pose rest, facing +Z, left = +X. Four 1-second gait cycles at 60 fps, so the
//! clip loops seamlessly. All angles are computed in `f64` and rounded once, so the bytes are
//! reproducible; `recordings/demo.rcr` is this output (checked by a test) and is embedded in the
//! binary by [`embedded_demo`].

use std::f64::consts::TAU;
use std::sync::Arc;

use glam::{DQuat, DVec3, Quat, Vec3};
use rigcast_retarget::{Clip, RawSkeleton, Skeleton, Transform};

use crate::error::SourceError;
use crate::recording::{clip_from_recording, read_recording, write_clip_recording};

/// Frames per second of the demo.
pub const DEMO_FPS: u32 = 60;
/// Number of frames (4 s).
pub const DEMO_FRAMES: usize = 240;
const CYCLE_SECS: f64 = 1.0;

static DEMO_BYTES: &[u8] = include_bytes!("../../recordings/demo.rcr");

/// The demo skeleton: 25 bones, T-pose rest, metres.
pub fn demo_skeleton() -> Arc<Skeleton> {
    let mut raw = RawSkeleton::default();
    let mut add = |name: &str, parent: Option<usize>, x: f32, y: f32, z: f32| {
        raw.add(
            name,
            parent,
            Transform::from_translation(Vec3::new(x, y, z)),
        )
    };
    let pelvis = add("pelvis", None, 0.0, 0.95, 0.0);
    let spine_lower = add("spine_lower", Some(pelvis), 0.0, 0.10, 0.0);
    let spine_upper = add("spine_upper", Some(spine_lower), 0.0, 0.12, 0.0);
    let chest = add("chest", Some(spine_upper), 0.0, 0.14, 0.0);
    let neck = add("neck", Some(chest), 0.0, 0.16, 0.0);
    let head = add("head", Some(neck), 0.0, 0.10, 0.0);
    add("head_top", Some(head), 0.0, 0.18, 0.0);
    for (side, s) in [("l", 1.0f32), ("r", -1.0)] {
        let clavicle = add(
            &format!("clavicle_{side}"),
            Some(chest),
            0.04 * s,
            0.12,
            0.0,
        );
        let upper = add(
            &format!("arm_upper_{side}"),
            Some(clavicle),
            0.14 * s,
            0.0,
            0.0,
        );
        let lower = add(
            &format!("arm_lower_{side}"),
            Some(upper),
            0.28 * s,
            0.0,
            0.0,
        );
        let hand = add(&format!("hand_{side}"), Some(lower), 0.25 * s, 0.0, 0.0);
        add(&format!("hand_tip_{side}"), Some(hand), 0.18 * s, 0.0, 0.0);
    }
    for (side, s) in [("l", 1.0f32), ("r", -1.0)] {
        let upper = add(
            &format!("leg_upper_{side}"),
            Some(pelvis),
            0.09 * s,
            -0.05,
            0.0,
        );
        let lower = add(&format!("leg_lower_{side}"), Some(upper), 0.0, -0.43, 0.0);
        let foot = add(&format!("foot_{side}"), Some(lower), 0.0, -0.42, 0.0);
        add(&format!("toes_{side}"), Some(foot), 0.0, -0.05, 0.13);
    }
    // The layout above is valid by construction.
    #[allow(clippy::expect_used)]
    Arc::new(Skeleton::build(&raw).expect("demo skeleton is valid"))
}

fn rx(a: f64) -> DQuat {
    DQuat::from_axis_angle(DVec3::X, a)
}
fn ry(a: f64) -> DQuat {
    DQuat::from_axis_angle(DVec3::Y, a)
}
fn rz(a: f64) -> DQuat {
    DQuat::from_axis_angle(DVec3::Z, a)
}

/// `x`, with a zero always +0.0. The sign of a zero carries no meaning here, but it reaches the
/// file's bytes, and `f64::max(-0.0, 0.0)` may return either zero (debug and release builds
/// differed on the toes' resting angle), so zeros are written one way.
fn unsigned_zero(x: f32) -> f32 {
    x + 0.0
}

/// Generates the demo clip (deterministic).
pub fn generate() -> Clip {
    let skeleton = demo_skeleton();
    let id = |name: &str| skeleton.bone(name).map(|b| b.index());
    let mut poses = Vec::with_capacity(DEMO_FRAMES);
    for k in 0..DEMO_FRAMES {
        let t = k as f64 / DEMO_FPS as f64;
        let phase = TAU * t / CYCLE_SECS;
        let (s, c) = phase.sin_cos();
        let mut rot: Vec<DQuat> = vec![DQuat::IDENTITY; skeleton.num_bones()];
        let mut set = |name: &str, q: DQuat| {
            if let Some(i) = id(name) {
                rot[i] = q;
            }
        };
        // Pelvis: yaw with the stride, slight roll toward the stance leg.
        set("pelvis", ry(0.08 * s) * rz(0.03 * c));
        set("spine_lower", rx(0.05));
        set("chest", ry(-0.12 * s));
        set("neck", ry(0.04 * s));
        set("head", rx(-0.04 + 0.03 * (2.0 * phase).cos()));
        // Legs: the left leg swings forward (negative X rotation) while the right swings back.
        for (side, sign) in [("l", 1.0), ("r", -1.0)] {
            let swing = -0.45 * sign * s;
            // The knee flexes most while its leg swings forward.
            let knee = 0.1 + 0.7 * (-sign * c).max(0.0).powi(2);
            set(&format!("leg_upper_{side}"), rx(swing));
            set(&format!("leg_lower_{side}"), rx(knee));
            set(
                &format!("foot_{side}"),
                rx(-0.3 * sign * s - 0.15 * (knee - 0.1)),
            );
            set(&format!("toes_{side}"), rx(0.2 * (sign * s).max(0.0)));
        }
        // Arms: lowered from the T-pose and swung opposite to their leg.
        for (side, sign) in [("l", 1.0), ("r", -1.0)] {
            let swing = 0.35 * sign * s;
            set(&format!("clavicle_{side}"), ry(-0.05 * sign * s));
            set(&format!("arm_upper_{side}"), rx(swing) * rz(-1.3 * sign));
            set(
                &format!("arm_lower_{side}"),
                ry(-sign * (0.25 + 0.15 * sign * s)),
            );
            set(&format!("hand_{side}"), rz(0.1 * sign));
        }
        let mut pose = skeleton.rest_pose();
        for (out, q) in pose.rotations.iter_mut().zip(&rot) {
            *out = Quat::from_array(q.normalize().as_quat().to_array().map(unsigned_zero));
        }
        // Two bobs per cycle: lowest at each heel strike.
        let bob = 0.025 * (2.0 * phase).cos();
        pose.translations[0] = Vec3::new((0.02 * c) as f32, (0.95 + bob) as f32, 0.0);
        poses.push(pose);
    }
    #[allow(clippy::expect_used)]
    Clip::new("demo_walk", skeleton, poses, 1.0 / DEMO_FPS as f64)
        .expect("demo poses fit the skeleton")
}

/// The demo as `.rcr` bytes (what `recordings/demo.rcr` holds).
pub fn generate_bytes() -> Result<Vec<u8>, SourceError> {
    write_clip_recording(Vec::new(), &generate())
}

/// The embedded demo recording, parsed.
pub fn embedded_demo() -> Result<Clip, SourceError> {
    let rec = read_recording(DEMO_BYTES)?;
    clip_from_recording(&rec, "demo_walk")
}

/// The embedded demo's raw bytes.
pub fn embedded_demo_bytes() -> &'static [u8] {
    DEMO_BYTES
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rigcast_retarget::world_transforms;

    #[test]
    fn committed_file_matches_the_generator() {
        let bytes = generate_bytes().unwrap();
        assert!(bytes.len() < 200_000, "{} bytes", bytes.len());
        assert!(
            bytes == DEMO_BYTES,
            "recordings/demo.rcr is stale: run `cargo run -p rigcast-sources --example make_demo`"
        );
    }

    #[test]
    fn embedded_demo_is_a_looping_walk() {
        let clip = embedded_demo().unwrap();
        assert_eq!(clip.skeleton.num_bones(), 25);
        assert_eq!(clip.num_frames(), DEMO_FRAMES);
        assert!((clip.fps() - 60.0).abs() < 1e-3);
        // The first frame follows the last one seamlessly: compare with a 241st frame.
        let w0 = world_transforms(&clip.skeleton, &clip.poses[0]);
        let w1 = world_transforms(&clip.skeleton, &clip.poses[1]);
        let wl = world_transforms(&clip.skeleton, &clip.poses[DEMO_FRAMES - 1]);
        let toe = clip.skeleton.bone("toes_l").unwrap().index();
        let step = (w1[toe].translation - w0[toe].translation).length();
        let wrap = (w0[toe].translation - wl[toe].translation).length();
        assert!(wrap < 2.0 * step + 1e-4, "wrap {wrap} vs step {step}");
        // Feet stay near the ground and the head near 1.7 m.
        let head = clip.skeleton.bone("head_top").unwrap().index();
        for p in &clip.poses {
            let w = world_transforms(&clip.skeleton, p);
            assert!((1.6..1.8).contains(&w[head].translation.y));
            assert!(w[toe].translation.y > -0.1 && w[toe].translation.y < 0.3);
        }
        // Hands hang below the shoulders (arms lowered from the T-pose).
        let hand = clip.skeleton.bone("hand_l").unwrap().index();
        let shoulder = clip.skeleton.bone("arm_upper_l").unwrap().index();
        assert!(w0[hand].translation.y < w0[shoulder].translation.y - 0.3);
    }
}
