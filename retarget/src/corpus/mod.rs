//! A labelled corpus of generated skeletons, for tests and benchmarks (no IO).
//!
//! Every entry has a ground-truth label per bone in the format of
//! [`crate::analysis::BoneRole::label`] (`hips`, `left_upper_arm`, `tail_3`…). [`all`] returns
//! each kind in T-pose, as an A-pose variant (arms rotated ~45° down as a rest-rotation change)
//! and as an anonymous copy (names `j0..jN`, child order shuffled).
//!
//! Bodies face +Z with the character's left at +X, in metres, standing on y = 0.

use glam::{Quat, Vec3};

pub use crate::procedural::{creatures, humanoid, Builder, Style};

use crate::skeleton::Skeleton;

/// What an entry is, for choosing test expectations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Two arms, two legs.
    Humanoid,
    /// Four legs (front legs labelled as arms).
    Quadruped,
    /// Humanoid with wings.
    Winged,
    /// Humanoid with two pairs of arms.
    FourArmed,
    /// Humanoid with a long tail.
    Tailed,
    /// The large benchmark creature.
    Creature,
}

/// Variant of a base skeleton.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// As built: T-pose, conventional names.
    TPose,
    /// Arms rotated 45° down.
    APose,
    /// Names `j0..jN`, children shuffled.
    Anonymous,
}

/// One corpus skeleton.
#[derive(Debug, Clone)]
pub struct CorpusEntry {
    /// e.g. `mixamo`, `mixamo_apose`, `mixamo_anon`.
    pub name: String,
    /// The skeleton.
    pub skeleton: Skeleton,
    /// Ground-truth role label per bone (indexed by `BoneId`).
    pub labels: Vec<String>,
    /// Kind of body.
    pub kind: Kind,
    /// Variant.
    pub variant: Variant,
}

fn base_builders() -> Vec<(&'static str, Kind, Builder)> {
    vec![
        ("mixamo", Kind::Humanoid, humanoid(Style::Mixamo, true)),
        ("unreal", Kind::Humanoid, humanoid(Style::Unreal, true)),
        ("rigify", Kind::Humanoid, humanoid(Style::Rigify, true)),
        (
            "cmu_cgspeed",
            Kind::Humanoid,
            humanoid(Style::CmuCgspeed, false),
        ),
        ("cmu_max", Kind::Humanoid, humanoid(Style::CmuMax, false)),
        ("smpl", Kind::Humanoid, humanoid(Style::Smpl, false)),
        (
            "mediapipe",
            Kind::Humanoid,
            humanoid(Style::MediaPipe, false),
        ),
        ("vrm", Kind::Humanoid, humanoid(Style::Vrm, true)),
        ("unity_x", Kind::Humanoid, humanoid(Style::UnityX, false)),
        ("head_top", Kind::Humanoid, humanoid(Style::HeadTop, false)),
        ("horse", Kind::Quadruped, creatures::horse()),
        ("winged", Kind::Winged, creatures::winged_biped()),
        ("four_armed", Kind::FourArmed, creatures::four_armed()),
        ("long_tailed", Kind::Tailed, creatures::long_tailed()),
    ]
}

/// Rotates every upper-arm subtree 45° down about the forward axis (arms of humanoids); a
/// quadruped's front legs swing 15° forward instead.
fn a_pose(b: &Builder, kind: Kind) -> Builder {
    let mut out = b.clone();
    let kind_is_quadruped = kind == Kind::Quadruped;
    for i in 0..out.labels.len() {
        let l = out.labels[i].clone();
        let left = l == "left_upper_arm" || l == "left_limb2_upper_arm";
        let right = l == "right_upper_arm" || l == "right_limb2_upper_arm";
        let quad_front = kind_is_quadruped && out.labels[i].ends_with("_clavicle");
        if quad_front {
            // A quadruped's "A-pose": front legs swung 15° forward at the shoulder blade.
            out.rotate_subtree(i, Quat::from_axis_angle(Vec3::X, (-15f32).to_radians()));
            continue;
        }
        if (left || right) && !kind_is_quadruped {
            // Left arm (+X) goes down: rotate about +Z by -45°; mirror for the right.
            let angle = if left { -45f32 } else { 45f32 };
            out.rotate_subtree(i, Quat::from_axis_angle(Vec3::Z, angle.to_radians()));
        }
    }
    out
}

fn entry(name: String, kind: Kind, variant: Variant, b: &Builder) -> Option<CorpusEntry> {
    let (skeleton, labels) = b.build()?;
    Some(CorpusEntry {
        name,
        skeleton,
        labels,
        kind,
        variant,
    })
}

/// Every corpus skeleton: 14 kinds × (T-pose, A-pose, anonymous) = 42 entries.
pub fn all() -> Vec<CorpusEntry> {
    let mut out = Vec::new();
    for (i, (name, kind, b)) in base_builders().into_iter().enumerate() {
        out.extend(entry(name.to_string(), kind, Variant::TPose, &b));
        out.extend(entry(
            format!("{name}_apose"),
            kind,
            Variant::APose,
            &a_pose(&b, kind),
        ));
        out.extend(entry(
            format!("{name}_anon"),
            kind,
            Variant::Anonymous,
            &b.anonymized(i as u64 + 1),
        ));
    }
    out
}

/// One entry by name (e.g. `"mixamo_apose"`).
pub fn get(name: &str) -> Option<CorpusEntry> {
    all().into_iter().find(|e| e.name == name)
}

/// The ~65-bone humanoid with fingers (Mixamo names) used by benchmarks.
pub fn humanoid_65() -> Option<CorpusEntry> {
    entry(
        "humanoid_65".into(),
        Kind::Humanoid,
        Variant::TPose,
        &humanoid(Style::Mixamo, true),
    )
}

/// The ~187-bone dragon-like creature used by benchmarks.
pub fn creature_187() -> Option<CorpusEntry> {
    entry(
        "creature_187".into(),
        Kind::Creature,
        Variant::TPose,
        &creatures::dragon(),
    )
}

/// A six-bone arm (clavicle … fingertip) and a four-bone arm (clavicle … wrist) on a minimal
/// body: seed 000's failure case. Returns (six, four).
pub fn seed000_arms() -> Option<(CorpusEntry, CorpusEntry)> {
    let six = humanoid(Style::Smpl, false);
    let mut six = six;
    // Add a fingertip after SMPL's "hand" joint so the arm has 6 bones.
    for left in [true, false] {
        let n = if left { "left_hand" } else { "right_hand" };
        let Some(h) = six.find(n) else { continue };
        let p = six.world_pos[h] + Vec3::new(if left { 0.05 } else { -0.05 }, 0.0, 0.0);
        let lab = if left {
            "left_index_2"
        } else {
            "right_index_2"
        };
        six.add(&format!("{n}_tip"), Some(h), p, lab);
    }
    let four = humanoid(Style::UnityX, false);
    Some((
        entry("arm6".into(), Kind::Humanoid, Variant::TPose, &six)?,
        entry("arm4".into(), Kind::Humanoid, Variant::TPose, &four)?,
    ))
}
