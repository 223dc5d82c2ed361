//! Non-humanoid fixtures: a horse-like quadruped, a winged biped, a four-armed biped, a
//! long-tailed biped and a ~187-bone dragon. Metres, rest pose standing, facing +Z.

use glam::{vec3, Vec3};

use super::builder::Builder;
use super::humanoid::{humanoid, Style};

fn m(v: Vec3, left: bool) -> Vec3 {
    if left {
        v
    } else {
        vec3(-v.x, v.y, v.z)
    }
}

fn sfx(left: bool) -> &'static str {
    if left {
        "L"
    } else {
        "R"
    }
}

fn lab(left: bool, role: &str) -> String {
    format!("{}_{role}", if left { "left" } else { "right" })
}

/// Adds a chain of bones at the given points; returns the last index.
fn chain(b: &mut Builder, parent: usize, pts: &[(String, Vec3, String)]) -> usize {
    let mut p = parent;
    for (name, pos, label) in pts {
        p = b.add(name, Some(p), *pos, label);
    }
    p
}

/// Horse-like quadruped: hind legs on the pelvis, front legs on the chest, neck, head, tail.
pub fn horse() -> Builder {
    let mut b = Builder::default();
    let pelvis = b.add("pelvis", None, vec3(0.0, 1.30, -0.60), "hips");
    let spine_pts = [
        ("spine1", vec3(0.0, 1.35, -0.20), "spine"),
        ("spine2", vec3(0.0, 1.38, 0.20), "spine_mid"),
        ("chest", vec3(0.0, 1.35, 0.55), "chest"),
    ];
    let mut p = pelvis;
    for (n, v, l) in spine_pts {
        p = b.add(n, Some(p), v, l);
    }
    let chest = p;
    let neck = [
        ("neck1", vec3(0.0, 1.55, 0.80), "neck"),
        ("neck2", vec3(0.0, 1.80, 0.95), "neck_2"),
        ("head", vec3(0.0, 1.95, 1.05), "head"),
        ("nose", vec3(0.0, 1.70, 1.50), "head_end"),
    ];
    let mut p = chest;
    for (n, v, l) in neck {
        p = b.add(n, Some(p), v, l);
    }
    let tail: Vec<(String, Vec3, String)> = (0..4)
        .map(|i| {
            let t = i as f32;
            (
                format!("tail{}", i + 1),
                vec3(0.0, 1.30 - 0.18 * t, -0.75 - 0.07 * t),
                format!("tail_{}", i + 1),
            )
        })
        .collect();
    chain(&mut b, pelvis, &tail);
    for left in [true, false] {
        let s = sfx(left);
        let hind = vec![
            (
                format!("hip.{s}"),
                m(vec3(0.2, 1.2, -0.6), left),
                lab(left, "upper_leg"),
            ),
            (
                format!("stifle.{s}"),
                m(vec3(0.2, 0.85, -0.45), left),
                lab(left, "lower_leg"),
            ),
            (
                format!("hock.{s}"),
                m(vec3(0.2, 0.50, -0.68), left),
                lab(left, "foot"),
            ),
            (
                format!("hind_fetlock.{s}"),
                m(vec3(0.2, 0.18, -0.60), left),
                lab(left, "toes"),
            ),
            (
                format!("hind_hoof.{s}"),
                m(vec3(0.2, 0.02, -0.55), left),
                lab(left, "toe_end"),
            ),
            (
                format!("hind_tip.{s}"),
                m(vec3(0.2, 0.0, -0.45), left),
                lab(left, "toe_end"),
            ),
        ];
        chain(&mut b, pelvis, &hind);
        let front = vec![
            (
                format!("scapula.{s}"),
                m(vec3(0.16, 1.32, 0.55), left),
                lab(left, "clavicle"),
            ),
            (
                format!("humerus.{s}"),
                m(vec3(0.2, 1.10, 0.62), left),
                lab(left, "upper_arm"),
            ),
            (
                format!("radius.{s}"),
                m(vec3(0.2, 0.82, 0.50), left),
                lab(left, "lower_arm"),
            ),
            (
                format!("cannon.{s}"),
                m(vec3(0.2, 0.48, 0.52), left),
                lab(left, "hand"),
            ),
            (
                format!("front_fetlock.{s}"),
                m(vec3(0.2, 0.22, 0.52), left),
                lab(left, "index_1"),
            ),
            (
                format!("front_hoof.{s}"),
                m(vec3(0.2, 0.03, 0.57), left),
                lab(left, "index_2"),
            ),
            (
                format!("front_tip.{s}"),
                m(vec3(0.2, 0.0, 0.66), left),
                lab(left, "index_3"),
            ),
        ];
        chain(&mut b, chest, &front);
    }
    b
}

/// Adds one wing (humerus, forearm, hand, `fingers` fingers of `joints` joints) to a builder.
fn wing(
    b: &mut Builder,
    parent: usize,
    left: bool,
    base: Vec3,
    span: f32,
    fingers: usize,
    joints: usize,
) {
    let s = sfx(left);
    let pts = vec![
        (
            format!("wing_root.{s}"),
            m(base, left),
            lab(left, "wing_clavicle"),
        ),
        (
            format!("wing_upper.{s}"),
            m(base + vec3(0.1 * span, 0.05 * span, -0.03 * span), left),
            lab(left, "wing_upper_arm"),
        ),
        (
            format!("wing_fore.{s}"),
            m(base + vec3(0.42 * span, 0.12 * span, -0.05 * span), left),
            lab(left, "wing_lower_arm"),
        ),
        (
            format!("wing_hand.{s}"),
            m(base + vec3(0.72 * span, 0.1 * span, -0.05 * span), left),
            lab(left, "wing_hand"),
        ),
    ];
    let hand = chain(b, parent, &pts);
    let hp = b.world_pos[hand];
    for f in 0..fingers {
        let ang = -0.2 - 1.1 * f as f32 / fingers.max(1) as f32;
        let dir = vec3(ang.cos(), ang.sin() * 0.3, ang.sin());
        let seg = 0.5 * span / joints as f32;
        let pts: Vec<(String, Vec3, String)> = (0..joints)
            .map(|j| {
                (
                    format!("wing_f{}_{}.{s}", f + 1, j + 1),
                    hp + m(dir, left) * (0.03 * span + seg * j as f32),
                    lab(left, "wing_finger"),
                )
            })
            .collect();
        chain(b, hand, &pts);
    }
}

/// A Mixamo-like biped with a pair of large wings on the upper back.
pub fn winged_biped() -> Builder {
    let mut b = humanoid(Style::Mixamo, false);
    let chest = b.find("mixamorig:Spine2").unwrap_or(0);
    for left in [true, false] {
        wing(&mut b, chest, left, vec3(0.08, 1.38, -0.12), 1.8, 3, 2);
    }
    b
}

/// A biped with two pairs of arms (the lower pair on the middle spine bone).
pub fn four_armed() -> Builder {
    let mut b = humanoid(Style::Mixamo, false);
    let mid = b.find("mixamorig:Spine1").unwrap_or(0);
    for left in [true, false] {
        let s = if left { "Left" } else { "Right" };
        let y = 1.20;
        let pts = vec![
            (
                format!("Lower{s}Shoulder"),
                m(vec3(0.03, y, 0.0), left),
                lab(left, "limb2_clavicle"),
            ),
            (
                format!("Lower{s}Arm"),
                m(vec3(0.17, y, 0.0), left),
                lab(left, "limb2_upper_arm"),
            ),
            (
                format!("Lower{s}ForeArm"),
                m(vec3(0.44, y, 0.0), left),
                lab(left, "limb2_lower_arm"),
            ),
            (
                format!("Lower{s}Hand"),
                m(vec3(0.69, y, 0.0), left),
                lab(left, "limb2_hand"),
            ),
            (
                format!("Lower{s}HandEnd"),
                m(vec3(0.78, y, 0.0), left),
                lab(left, "limb2_index_1"),
            ),
        ];
        chain(&mut b, mid, &pts);
    }
    b
}

/// A biped with a long (10-bone) tail from the hips, backwards and down.
pub fn long_tailed() -> Builder {
    let mut b = humanoid(Style::UnityX, false);
    // Built along X already; add the tail then recompute the along-X rotations.
    let hips = b.find("Hips").unwrap_or(0);
    let pts: Vec<(String, Vec3, String)> = (0..10)
        .map(|i| {
            let t = (i + 1) as f32;
            (
                format!("Tail{:02}", i + 1),
                vec3(0.0, 0.92 - 0.06 * t, -0.06 - 0.11 * t),
                format!("tail_{}", i + 1),
            )
        })
        .collect();
    chain(&mut b, hips, &pts);
    b.bones_along_x();
    b
}

/// Dragon-like creature with 187 bones: four legs with clawed toes, winged arms with long
/// fingers, a long neck with jaw, a long tail.
pub fn dragon() -> Builder {
    let mut b = Builder::default();
    let pelvis = b.add("pelvis", None, vec3(0.0, 1.6, -1.0), "hips");
    let mut p = pelvis;
    for i in 0..6 {
        let t = (i + 1) as f32;
        let label = match i {
            0 => "spine".to_string(),
            5 => "chest".to_string(),
            _ => "spine_mid".to_string(),
        };
        p = b.add(
            &format!("spine{}", i + 1),
            Some(p),
            vec3(0.0, 1.6 + 0.03 * t, -1.0 + 0.35 * t),
            &label,
        );
    }
    let chest = p;
    let chest_pos = b.world_pos[chest];
    for i in 0..10 {
        let t = (i + 1) as f32;
        let label = if i == 0 {
            "neck".into()
        } else {
            format!("neck_{}", i + 1)
        };
        p = b.add(
            &format!("neck{}", i + 1),
            Some(p),
            chest_pos + vec3(0.0, 0.2 * t, 0.12 * t),
            &label,
        );
    }
    let head_pos = b.world_pos[p] + vec3(0.0, 0.15, 0.15);
    let head = b.add("head", Some(p), head_pos, "head");
    let jaw = b.add("jaw", Some(head), head_pos + vec3(0.0, -0.1, 0.1), "jaw");
    b.add(
        "jaw_end",
        Some(jaw),
        head_pos + vec3(0.0, -0.15, 0.35),
        "helper",
    );
    b.add(
        "head_end",
        Some(head),
        head_pos + vec3(0.0, 0.05, 0.6),
        "head_end",
    );
    let mut p = pelvis;
    for i in 0..20 {
        let t = (i + 1) as f32;
        p = b.add(
            &format!("tail{}", i + 1),
            Some(p),
            vec3(0.0, 1.6 - 0.05 * t, -1.0 - 0.25 * t),
            &format!("tail_{}", i + 1),
        );
    }
    for left in [true, false] {
        dragon_limbs(&mut b, pelvis, chest, left);
    }
    b
}

/// One side of the dragon: hind leg with claws, foreleg with claws, and a wing.
fn dragon_limbs(b: &mut Builder, pelvis: usize, chest: usize, left: bool) {
    let s = sfx(left);
    // Hind leg: thigh, shin, foot (+ helper ankle), 4 toes × 3.
    let hind = vec![
        (
            format!("thigh.{s}"),
            m(vec3(0.35, 1.5, -1.0), left),
            lab(left, "upper_leg"),
        ),
        (
            format!("shin.{s}"),
            m(vec3(0.4, 0.9, -0.8), left),
            lab(left, "lower_leg"),
        ),
        (
            format!("ankle.{s}"),
            m(vec3(0.4, 0.35, -1.0), left),
            lab(left, "foot"),
        ),
        (
            format!("hind_foot.{s}"),
            m(vec3(0.4, 0.08, -0.9), left),
            lab(left, "toes"),
        ),
    ];
    let foot = chain(b, pelvis, &hind);
    claws(b, foot, left, "hind", 3);
    let front = vec![
        (
            format!("shoulder.{s}"),
            m(vec3(0.2, 1.75, 1.0), left),
            lab(left, "clavicle"),
        ),
        (
            format!("upper_arm.{s}"),
            m(vec3(0.4, 1.55, 1.05), left),
            lab(left, "upper_arm"),
        ),
        (
            format!("forearm.{s}"),
            m(vec3(0.42, 0.95, 1.15), left),
            lab(left, "lower_arm"),
        ),
        (
            format!("hand.{s}"),
            m(vec3(0.42, 0.42, 1.05), left),
            lab(left, "hand"),
        ),
    ];
    let hand = chain(b, chest, &front);
    claws(b, hand, left, "front", 3);
    // Wings: 4 fingers of 9 joints plus a one-joint thumb.
    let before = b.names.len();
    wing(b, chest, left, vec3(0.15, 1.85, 0.8), 4.0, 4, 9);
    let wing_hand = b.find(&format!("wing_hand.{s}")).unwrap_or(before);
    let whp = b.world_pos[wing_hand];
    b.add(
        &format!("wing_thumb.{s}"),
        Some(wing_hand),
        whp + m(vec3(0.1, 0.0, 0.2), left),
        &lab(left, "wing_finger"),
    );
}

fn claws(b: &mut Builder, parent: usize, left: bool, prefix: &str, joints: usize) {
    let s = sfx(left);
    let base = b.world_pos[parent];
    for c in 0..4 {
        let ang = -0.6 + 0.4 * c as f32;
        let dir = vec3(ang.sin(), -0.15, ang.cos());
        let pts: Vec<(String, Vec3, String)> = (0..joints)
            .map(|j| {
                (
                    format!("{prefix}_claw{}_{}.{s}", c + 1, j + 1),
                    base + m(dir, left) * (0.08 + 0.08 * j as f32),
                    lab(left, "claw"),
                )
            })
            .collect();
        chain(b, parent, &pts);
    }
}
