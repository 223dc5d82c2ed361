//! Non-humanoid bodies built from code: a horse-like quadruped, a winged biped, a four-armed
//! biped, a long-tailed biped and a ~187-bone dragon (the benchmark workloads' creature).
//! Metres, rest pose standing, facing +Z; every bone labelled with its role.

use glam::{vec3, Vec3};

use super::{humanoid, Builder, Style};

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

/// Adds a chain of bones at the given points (name, position, label); returns the last index.
fn chain(
    b: &mut Builder,
    parent: usize,
    pts: &[(impl AsRef<str>, Vec3, impl AsRef<str>)],
) -> usize {
    let mut p = parent;
    for (name, pos, label) in pts {
        p = b.add(name.as_ref(), Some(p), *pos, label.as_ref());
    }
    p
}

/// Adds a chain of one side's bones given as (name, left-side position, role), like
/// [`chain`]: each name gets the side's suffix (`hip.L`), each position is mirrored for the
/// right side and each label says the side (`left_upper_leg`). Returns the last index.
fn side_chain(b: &mut Builder, parent: usize, left: bool, pts: &[(&str, Vec3, &str)]) -> usize {
    let s = sfx(left);
    let mut p = parent;
    for (name, pos, role) in pts {
        p = b.add(
            &format!("{name}.{s}"),
            Some(p),
            m(*pos, left),
            &lab(left, role),
        );
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
    let chest = chain(&mut b, pelvis, &spine_pts);
    let neck = [
        ("neck1", vec3(0.0, 1.55, 0.80), "neck"),
        ("neck2", vec3(0.0, 1.80, 0.95), "neck_2"),
        ("head", vec3(0.0, 1.95, 1.05), "head"),
        ("nose", vec3(0.0, 1.70, 1.50), "head_end"),
    ];
    chain(&mut b, chest, &neck);
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
        let hind = [
            ("hip", vec3(0.2, 1.2, -0.6), "upper_leg"),
            ("stifle", vec3(0.2, 0.85, -0.45), "lower_leg"),
            ("hock", vec3(0.2, 0.50, -0.68), "foot"),
            ("hind_fetlock", vec3(0.2, 0.18, -0.60), "toes"),
            ("hind_hoof", vec3(0.2, 0.02, -0.55), "toe_end"),
            ("hind_tip", vec3(0.2, 0.0, -0.45), "toe_end"),
        ];
        side_chain(&mut b, pelvis, left, &hind);
        let front = [
            ("scapula", vec3(0.16, 1.32, 0.55), "clavicle"),
            ("humerus", vec3(0.2, 1.10, 0.62), "upper_arm"),
            ("radius", vec3(0.2, 0.82, 0.50), "lower_arm"),
            ("cannon", vec3(0.2, 0.48, 0.52), "hand"),
            ("front_fetlock", vec3(0.2, 0.22, 0.52), "index_1"),
            ("front_hoof", vec3(0.2, 0.03, 0.57), "index_2"),
            ("front_tip", vec3(0.2, 0.0, 0.66), "index_3"),
        ];
        side_chain(&mut b, chest, left, &front);
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
    let pts = [
        ("wing_root", base, "wing_clavicle"),
        (
            "wing_upper",
            base + vec3(0.1 * span, 0.05 * span, -0.03 * span),
            "wing_upper_arm",
        ),
        (
            "wing_fore",
            base + vec3(0.42 * span, 0.12 * span, -0.05 * span),
            "wing_lower_arm",
        ),
        (
            "wing_hand",
            base + vec3(0.72 * span, 0.1 * span, -0.05 * span),
            "wing_hand",
        ),
    ];
    let hand = side_chain(b, parent, left, &pts);
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
        // (name after `Lower{Side}`, distance out along the arm, role)
        let pts = [
            ("Shoulder", 0.03, "limb2_clavicle"),
            ("Arm", 0.17, "limb2_upper_arm"),
            ("ForeArm", 0.44, "limb2_lower_arm"),
            ("Hand", 0.69, "limb2_hand"),
            ("HandEnd", 0.78, "limb2_index_1"),
        ]
        .map(|(name, x, role)| {
            (
                format!("Lower{s}{name}"),
                m(vec3(x, y, 0.0), left),
                lab(left, role),
            )
        });
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
    let hind = [
        ("thigh", vec3(0.35, 1.5, -1.0), "upper_leg"),
        ("shin", vec3(0.4, 0.9, -0.8), "lower_leg"),
        ("ankle", vec3(0.4, 0.35, -1.0), "foot"),
        ("hind_foot", vec3(0.4, 0.08, -0.9), "toes"),
    ];
    let foot = side_chain(b, pelvis, left, &hind);
    claws(b, foot, left, "hind", 3);
    let front = [
        ("shoulder", vec3(0.2, 1.75, 1.0), "clavicle"),
        ("upper_arm", vec3(0.4, 1.55, 1.05), "upper_arm"),
        ("forearm", vec3(0.42, 0.95, 1.15), "lower_arm"),
        ("hand", vec3(0.42, 0.42, 1.05), "hand"),
    ];
    let hand = side_chain(b, chest, left, &front);
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
