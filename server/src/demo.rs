//! A small procedural clip used when the bundled demo recording is unavailable, and by tests
//! that need a known animation without files: a 15-bone humanoid that sways and waves.

use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_retarget::{Clip, Pose, RawSkeleton, RetargetError, Skeleton, Transform};

/// Builds the procedural demo clip: `num_frames` frames at `fps`, one full motion cycle.
pub fn procedural_clip(num_frames: usize, fps: f64) -> Result<Clip, RetargetError> {
    let mut raw = RawSkeleton::default();
    let t = |x: f32, y: f32, z: f32| Transform::from_translation(Vec3::new(x, y, z));
    let hips = raw.add("Hips", None, t(0.0, 0.95, 0.0));
    let spine = raw.add("Spine", Some(hips), t(0.0, 0.12, 0.0));
    let chest = raw.add("Chest", Some(spine), t(0.0, 0.2, 0.0));
    let neck = raw.add("Neck", Some(chest), t(0.0, 0.22, 0.0));
    raw.add("Head", Some(neck), t(0.0, 0.1, 0.0));
    for (side, x) in [("Left", 1.0f32), ("Right", -1.0)] {
        let upper = raw.add(
            format!("{side}UpperArm"),
            Some(chest),
            t(0.18 * x, 0.18, 0.0),
        );
        let lower = raw.add(
            format!("{side}LowerArm"),
            Some(upper),
            t(0.28 * x, 0.0, 0.0),
        );
        raw.add(format!("{side}Hand"), Some(lower), t(0.25 * x, 0.0, 0.0));
        let thigh = raw.add(
            format!("{side}UpperLeg"),
            Some(hips),
            t(0.09 * x, -0.05, 0.0),
        );
        let shin = raw.add(format!("{side}LowerLeg"), Some(thigh), t(0.0, -0.42, 0.0));
        raw.add(format!("{side}Foot"), Some(shin), t(0.0, -0.42, 0.0));
    }
    let skeleton = Arc::new(Skeleton::build(&raw)?);
    let n = num_frames.max(1);
    let poses = (0..n)
        .map(|i| {
            let phase = i as f32 / n as f32 * std::f32::consts::TAU;
            let mut pose = Pose::from_rest(&skeleton);
            let mut set = |name: &str, q: Quat| {
                if let Some(b) = skeleton.bone(name) {
                    pose.rotations[b.index()] = q;
                }
            };
            set("Spine", Quat::from_rotation_z(0.08 * phase.sin()));
            set("Head", Quat::from_rotation_y(0.4 * phase.sin()));
            set(
                "LeftUpperArm",
                Quat::from_rotation_z(0.9 + 0.5 * (2.0 * phase).sin()),
            );
            set("LeftLowerArm", Quat::from_rotation_y(0.6 * phase.cos()));
            set("RightUpperArm", Quat::from_rotation_z(-1.2));
            set("LeftUpperLeg", Quat::from_rotation_x(0.3 * phase.sin()));
            set("RightUpperLeg", Quat::from_rotation_x(-0.3 * phase.sin()));
            let mut hips_at = pose.root_translation();
            hips_at.x += 0.05 * phase.sin();
            pose.set_root_translation(hips_at);
            pose
        })
        .collect();
    Clip::new("procedural_demo", skeleton, poses, 1.0 / fps)
}
