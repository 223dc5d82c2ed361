//! Built-in characters (`builtin:NAME` targets). The default demo retargets the bundled walk
//! onto `mannequin`: a UE-mannequin-style humanoid (ground root, pelvis, spine_01…, clavicles,
//! twist bones, fingers) in A-pose, taller and with shorter forearms than the recording's
//! skeleton, so the demo shows retargeting across structure, rest posture and proportions.
//! Built from code (no file), so the engine's own tests use it too; the host loads characters
//! by name or file through `character::load_character`.

use glam::{Quat, Vec3};
use rigcast_retarget::procedural::{humanoid, Style};
use rigcast_retarget::Skeleton;

/// Prefix of built-in characters in target paths (`builtin:mannequin`).
pub const BUILTIN_PREFIX: &str = "builtin:";

/// Names accepted after `builtin:`.
pub const BUILTIN_NAMES: [&str; 1] = ["mannequin"];

/// A built-in character by name.
pub fn builtin(name: &str) -> Option<Skeleton> {
    match name {
        "mannequin" => mannequin(),
        _ => None,
    }
}

/// The demo character (see the module docs).
pub fn mannequin() -> Option<Skeleton> {
    let mut b = humanoid(Style::Unreal, true);
    // A-pose: each upper-arm subtree 45° down about the forward axis (left arm is at +X).
    for (name, angle) in [("upperarm_l", -45f32), ("upperarm_r", 45f32)] {
        let i = b.find(name)?;
        b.rotate_subtree(i, Quat::from_axis_angle(Vec3::Z, angle.to_radians()));
    }
    let mut raw = b.raw();
    // Different proportions: 12 % taller overall, forearms and hands 15 % shorter.
    for bone in &mut raw.bones {
        let mut s = 1.12;
        if bone.name.starts_with("hand_") {
            s *= 0.85;
        }
        bone.rest.translation *= s;
    }
    Skeleton::build(&raw).ok()
}
