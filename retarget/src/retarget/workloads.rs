//! Fixed, documented benchmark workloads (used by `retarget/benches/retarget.rs` and
//! `rigcast bench`), built in code so every machine measures the same thing:
//!
//! - [`cmu_like_31`]: a 31-bone CMU-style source (cgspeed names, arms hanging at rest, zero-length
//!   hip/back joints), centimetre-free metres.
//! - [`humanoid_65`]: a 65-bone Mixamo-style target in A-pose with finger chains and
//!   glTF-style bone axes (each bone's +Y along the bone).
//! - [`creature_187`]: a 187-bone winged, four-legged creature with a long neck and tail.
//! - [`walk`]: a deterministic 120-frame procedural motion for any skeleton.
//!
//! The workload pairs ([`humanoid_from_cmu`], [`creature_from_humanoid`]) come with name-based
//! mapping tables so the benchmark measures retargeting, not automatic mapping.

use glam::{Quat, Vec3};

use crate::mapping::{BoneOptions, MappingTable, SourceRef, TargetEntry};
use crate::pose::Pose;
use crate::skeleton::{RawSkeleton, Skeleton, Transform};

/// A skeleton under construction from world joint positions.
struct Builder {
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    positions: Vec<Vec3>,
}

impl Builder {
    fn new() -> Builder {
        Builder {
            names: Vec::new(),
            parents: Vec::new(),
            positions: Vec::new(),
        }
    }

    fn add(&mut self, name: impl Into<String>, parent: Option<usize>, position: Vec3) -> usize {
        self.names.push(name.into());
        self.parents.push(parent);
        self.positions.push(position);
        self.names.len() - 1
    }

    /// A straight chain of `n` bones from `parent`, starting at `start`, `step` apart.
    fn chain(&mut self, prefix: &str, parent: usize, start: Vec3, step: Vec3, n: usize) -> usize {
        let mut p = parent;
        for i in 0..n {
            p = self.add(
                format!("{prefix}{}", i + 1),
                Some(p),
                start + step * i as f32,
            );
        }
        p
    }

    /// `along_bone`: each bone's rest rotation turns its +Y onto its first child (glTF style);
    /// otherwise all rest rotations are identity (BVH style).
    fn build(&self, along_bone: bool) -> Skeleton {
        let n = self.names.len();
        let world: Vec<Quat> = (0..n)
            .map(|i| {
                if !along_bone {
                    return Quat::IDENTITY;
                }
                let child = (0..n).find(|&c| self.parents[c] == Some(i));
                let dir = child
                    .map(|c| self.positions[c] - self.positions[i])
                    .and_then(Vec3::try_normalize);
                dir.map(|d| Quat::from_rotation_arc(Vec3::Y, d))
                    .unwrap_or(Quat::IDENTITY)
            })
            .collect();
        let mut raw = RawSkeleton::default();
        for i in 0..n {
            let rest = match self.parents[i] {
                Some(p) => Transform {
                    translation: world[p].inverse() * (self.positions[i] - self.positions[p]),
                    rotation: world[p].inverse() * world[i],
                },
                None => Transform {
                    translation: self.positions[i],
                    rotation: world[i],
                },
            };
            raw.add(self.names[i].clone(), self.parents[i], rest);
        }
        // The builders above only ever produce valid trees; an empty skeleton is the fallback
        // that keeps this infallible without unwrap.
        Skeleton::build(&raw).unwrap_or_else(|_| {
            let mut one = RawSkeleton::default();
            one.add("root", None, Transform::IDENTITY);
            Skeleton::build(&one).unwrap_or_else(|_| unreachable!())
        })
    }
}

/// The 31-bone CMU-style source skeleton (see the module docs).
pub fn cmu_like_31() -> Skeleton {
    let mut b = Builder::new();
    let hips = b.add("Hips", None, Vec3::new(0.0, 0.95, 0.0));
    for (side, s) in [("Left", 1.0f32), ("Right", -1.0f32)] {
        let short = if s > 0.0 { "L" } else { "R" };
        let j = b.add(
            format!("{short}HipJoint"),
            Some(hips),
            Vec3::new(0.0, 0.95, 0.0),
        );
        let up = b.add(
            format!("{side}UpLeg"),
            Some(j),
            Vec3::new(s * 0.09, 0.87, 0.03),
        );
        let leg = b.add(
            format!("{side}Leg"),
            Some(up),
            Vec3::new(s * 0.24, 0.47, 0.03),
        );
        let foot = b.add(
            format!("{side}Foot"),
            Some(leg),
            Vec3::new(s * 0.38, 0.08, 0.03),
        );
        b.add(
            format!("{side}ToeBase"),
            Some(foot),
            Vec3::new(s * 0.39, 0.02, 0.16),
        );
    }
    let lower = b.add("LowerBack", Some(hips), Vec3::new(0.0, 0.95, 0.0));
    let spine = b.add("Spine", Some(lower), Vec3::new(0.0, 1.07, 0.0));
    let spine1 = b.add("Spine1", Some(spine), Vec3::new(0.0, 1.19, 0.0));
    let neck = b.add("Neck", Some(spine1), Vec3::new(0.0, 1.40, 0.0));
    let neck1 = b.add("Neck1", Some(neck), Vec3::new(0.0, 1.49, 0.01));
    b.add("Head", Some(neck1), Vec3::new(0.0, 1.57, 0.01));
    for (side, s) in [("Left", 1.0f32), ("Right", -1.0f32)] {
        let short = if s > 0.0 { "L" } else { "R" };
        let sh = b.add(
            format!("{side}Shoulder"),
            Some(spine1),
            Vec3::new(0.0, 1.40, 0.0),
        );
        let arm = b.add(
            format!("{side}Arm"),
            Some(sh),
            Vec3::new(s * 0.18, 1.38, 0.0),
        );
        let fore = b.add(
            format!("{side}ForeArm"),
            Some(arm),
            Vec3::new(s * 0.18, 1.10, 0.0),
        );
        let hand = b.add(
            format!("{side}Hand"),
            Some(fore),
            Vec3::new(s * 0.18, 0.85, 0.0),
        );
        let fb = b.add(
            format!("{side}FingerBase"),
            Some(hand),
            Vec3::new(s * 0.18, 0.81, 0.0),
        );
        b.add(
            format!("{side}HandIndex1"),
            Some(fb),
            Vec3::new(s * 0.18, 0.77, 0.0),
        );
        b.add(
            format!("{short}Thumb"),
            Some(hand),
            Vec3::new(s * 0.18, 0.82, 0.03),
        );
    }
    b.build(false)
}

const FINGERS: [&str; 5] = ["Thumb", "Index", "Middle", "Ring", "Pinky"];

/// The 65-bone Mixamo-style A-pose target (see the module docs).
pub fn humanoid_65() -> Skeleton {
    let mut b = Builder::new();
    let hips = b.add("Hips", None, Vec3::new(0.0, 1.0, 0.0));
    let spine = b.add("Spine", Some(hips), Vec3::new(0.0, 1.1, 0.0));
    let spine1 = b.add("Spine1", Some(spine), Vec3::new(0.0, 1.22, 0.0));
    let spine2 = b.add("Spine2", Some(spine1), Vec3::new(0.0, 1.34, 0.0));
    let neck = b.add("Neck", Some(spine2), Vec3::new(0.0, 1.5, 0.0));
    let head = b.add("Head", Some(neck), Vec3::new(0.0, 1.6, 0.02));
    b.add("HeadTop_End", Some(head), Vec3::new(0.0, 1.8, 0.02));
    let a = std::f32::consts::FRAC_PI_4;
    for (side, s) in [("Left", 1.0f32), ("Right", -1.0f32)] {
        let d = Vec3::new(s * a.cos(), -a.sin(), 0.0);
        let sh = b.add(
            format!("{side}Shoulder"),
            Some(spine2),
            Vec3::new(s * 0.05, 1.45, 0.0),
        );
        let arm_at = Vec3::new(s * 0.18, 1.45, 0.0);
        let arm = b.add(format!("{side}Arm"), Some(sh), arm_at);
        let fore = b.add(format!("{side}ForeArm"), Some(arm), arm_at + d * 0.28);
        let hand_at = arm_at + d * 0.53;
        let hand = b.add(format!("{side}Hand"), Some(fore), hand_at);
        for (k, f) in FINGERS.iter().enumerate() {
            let spread = Vec3::new(0.0, 0.0, 0.02 * (k as f32 - 2.0));
            b.chain(
                &format!("{side}Hand{f}"),
                hand,
                hand_at + d * 0.08 + spread,
                d * 0.03,
                4,
            );
        }
        let up = b.add(
            format!("{side}UpLeg"),
            Some(hips),
            Vec3::new(s * 0.1, 0.95, 0.0),
        );
        let leg = b.add(
            format!("{side}Leg"),
            Some(up),
            Vec3::new(s * 0.1, 0.52, 0.0),
        );
        let foot = b.add(
            format!("{side}Foot"),
            Some(leg),
            Vec3::new(s * 0.1, 0.09, 0.0),
        );
        let toe = b.add(
            format!("{side}ToeBase"),
            Some(foot),
            Vec3::new(s * 0.1, 0.02, 0.13),
        );
        b.add(
            format!("{side}Toe_End"),
            Some(toe),
            Vec3::new(s * 0.1, 0.02, 0.2),
        );
    }
    b.build(true)
}

/// The 187-bone creature (see the module docs).
pub fn creature_187() -> Skeleton {
    let mut b = Builder::new();
    let root = b.add("pelvis", None, Vec3::new(0.0, 1.2, 0.0));
    let spine = b.chain(
        "spine_",
        root,
        Vec3::new(0.0, 1.25, 0.2),
        Vec3::new(0.0, 0.02, 0.2),
        6,
    );
    let neck = b.chain(
        "neck_",
        spine,
        Vec3::new(0.0, 1.5, 1.4),
        Vec3::new(0.0, 0.15, 0.12),
        10,
    );
    let head = b.add("head", Some(neck), Vec3::new(0.0, 3.1, 2.6));
    b.add("jaw", Some(head), Vec3::new(0.0, 3.0, 2.7));
    b.add("eye_l", Some(head), Vec3::new(0.08, 3.15, 2.7));
    b.add("eye_r", Some(head), Vec3::new(-0.08, 3.15, 2.7));
    b.chain(
        "tail_",
        root,
        Vec3::new(0.0, 1.15, -0.2),
        Vec3::new(0.0, -0.02, -0.18),
        30,
    );
    for (side, s) in [("l", 1.0f32), ("r", -1.0f32)] {
        for (leg, parent, z) in [("front", spine, 1.2f32), ("hind", root, 0.0)] {
            let top = Vec3::new(s * 0.3, 1.2, z);
            let mut p = parent;
            for (k, part) in ["hip", "thigh", "shin", "ankle", "foot"].iter().enumerate() {
                let at = top + Vec3::new(s * 0.05 * k as f32, -0.27 * k as f32, 0.0);
                p = b.add(format!("{leg}_{part}_{side}"), Some(p), at);
            }
            for t in 0..4 {
                let at = top + Vec3::new(s * (0.2 + 0.04 * t as f32), -1.1, 0.1);
                b.chain(
                    &format!("{leg}_toe{t}_{side}_"),
                    p,
                    at,
                    Vec3::new(0.0, -0.02, 0.05),
                    3,
                );
            }
        }
        let wing_at = Vec3::new(s * 0.3, 1.45, 1.0);
        let mut w = spine;
        for (k, part) in ["wing_shoulder", "wing_arm", "wing_forearm", "wing_hand"]
            .iter()
            .enumerate()
        {
            w = b.add(
                format!("{part}_{side}"),
                Some(w),
                wing_at + Vec3::new(s * 0.5 * k as f32, 0.1, 0.0),
            );
        }
        for f in 0..5 {
            let at = wing_at + Vec3::new(s * 1.6, 0.1, -0.1 * f as f32);
            let dir = Vec3::new(s * 0.3, 0.05, -0.15 * f as f32);
            b.chain(&format!("wing_finger{f}_{side}_"), w, at, dir, 5);
        }
    }
    // Dorsal spikes along the spine bring the count to 187.
    let mut k = 0;
    while b.names.len() < 187 {
        let parent = (k % 6) + 1;
        let at = b.positions[parent] + Vec3::new(0.0, 0.1 + 0.01 * (k / 6) as f32, 0.0);
        b.add(format!("spike_{k}"), Some(parent), at);
        k += 1;
    }
    b.build(true)
}

/// A deterministic walk-like motion: every bone swings about its own axis with its own phase,
/// the root travels forward and bobs.
pub fn walk(skeleton: &Skeleton, num_frames: usize) -> Vec<Pose> {
    let rest = skeleton.rest_pose();
    (0..num_frames)
        .map(|f| {
            let t = f as f32 / 60.0;
            let mut p = rest.clone();
            for (i, r) in p.rotations.iter_mut().enumerate() {
                let k = i as f32;
                let axis = Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), 0.5).normalize_or_zero();
                *r = rest.rotations[i] * Quat::from_axis_angle(axis, 0.4 * (3.0 * t + k).sin());
            }
            p.translations[0] += Vec3::new(0.0, 0.03 * (6.0 * t).sin(), 1.3 * t);
            p
        })
        .collect()
}

/// A source, a target, a mapping table and source poses.
#[derive(Debug, Clone)]
pub struct Workload {
    /// Source skeleton.
    pub source: Skeleton,
    /// Target skeleton.
    pub target: Skeleton,
    /// Target → source table.
    pub table: MappingTable,
    /// Source poses to feed.
    pub poses: Vec<Pose>,
}

fn table(source: &Skeleton, target: &Skeleton, pairs: &[(&str, &str, f32)]) -> MappingTable {
    let mut t = MappingTable::empty(target.num_bones());
    for &(tn, sn, delay_secs) in pairs {
        if let (Some(tb), Some(sb)) = (target.bone(tn), source.bone(sn)) {
            t.entries[tb.index()] = Some(TargetEntry {
                sources: vec![SourceRef {
                    input: 0,
                    bone: sb,
                    weight: 1.0,
                }],
                options: BoneOptions {
                    delay_secs,
                    ..BoneOptions::default()
                },
                score: 0.0,
                evidence: vec!["workload".into()],
            });
        }
    }
    t
}

/// 65-bone humanoid ← 31-bone CMU-style source (22 body bones mapped; fingers held at rest).
pub fn humanoid_from_cmu() -> Workload {
    let source = cmu_like_31();
    let target = humanoid_65();
    let mut pairs: Vec<(String, String)> = [
        ("Hips", "Hips"),
        ("Spine", "LowerBack"),
        ("Spine1", "Spine"),
        ("Spine2", "Spine1"),
        ("Neck", "Neck"),
        ("Head", "Head"),
    ]
    .iter()
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    for side in ["Left", "Right"] {
        for (t, s) in [
            ("Shoulder", "Shoulder"),
            ("Arm", "Arm"),
            ("ForeArm", "ForeArm"),
            ("Hand", "Hand"),
            ("HandIndex1", "HandIndex1"),
            ("UpLeg", "UpLeg"),
            ("Leg", "Leg"),
            ("Foot", "Foot"),
            ("ToeBase", "ToeBase"),
        ] {
            pairs.push((format!("{side}{t}"), format!("{side}{s}")));
        }
    }
    let pairs: Vec<(&str, &str, f32)> = pairs
        .iter()
        .map(|(a, b)| (a.as_str(), b.as_str(), 0.0))
        .collect();
    let table = table(&source, &target, &pairs);
    let poses = walk(&source, 120);
    Workload {
        source,
        target,
        table,
        poses,
    }
}

/// 187-bone creature ← 65-bone humanoid: spine, neck and head from the spine, hind legs from
/// the legs, front legs and wings from the arms, the tail from the spine with growing delays.
pub fn creature_from_humanoid() -> Workload {
    let source = humanoid_65();
    let target = creature_187();
    let mut pairs: Vec<(String, String, f32)> = vec![("pelvis".into(), "Hips".into(), 0.0)];
    let spine_src = ["Spine", "Spine", "Spine1", "Spine1", "Spine2", "Spine2"];
    for (i, s) in spine_src.iter().enumerate() {
        pairs.push((format!("spine_{}", i + 1), s.to_string(), 0.0));
    }
    for i in 1..=10 {
        pairs.push((format!("neck_{i}"), "Neck".into(), 0.0));
    }
    pairs.push(("head".into(), "Head".into(), 0.0));
    for i in 1..=30 {
        pairs.push((format!("tail_{i}"), "Spine".into(), 0.01 * i as f32));
    }
    for (side, s) in [("l", "Left"), ("r", "Right")] {
        for (leg, src) in [
            ("hind", ["UpLeg", "UpLeg", "Leg", "Foot", "ToeBase"]),
            (
                "front",
                ["Shoulder", "Arm", "ForeArm", "Hand", "HandMiddle1"],
            ),
        ] {
            for (part, sp) in ["hip", "thigh", "shin", "ankle", "foot"].iter().zip(src) {
                pairs.push((format!("{leg}_{part}_{side}"), format!("{s}{sp}"), 0.0));
            }
        }
        for (part, sp) in ["wing_shoulder", "wing_arm", "wing_forearm", "wing_hand"]
            .iter()
            .zip(["Shoulder", "Arm", "ForeArm", "Hand"])
        {
            pairs.push((format!("{part}_{side}"), format!("{s}{sp}"), 0.0));
        }
        for (f, name) in FINGERS.iter().enumerate() {
            for j in 1..=4 {
                pairs.push((
                    format!("wing_finger{f}_{side}_{j}"),
                    format!("{s}Hand{name}{j}"),
                    0.0,
                ));
            }
        }
    }
    let pairs: Vec<(&str, &str, f32)> = pairs
        .iter()
        .map(|(a, b, d)| (a.as_str(), b.as_str(), *d))
        .collect();
    let table = table(&source, &target, &pairs);
    let poses = walk(&source, 120);
    Workload {
        source,
        target,
        table,
        poses,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workloads_have_their_documented_sizes() {
        assert_eq!(cmu_like_31().num_bones(), 31);
        assert_eq!(humanoid_65().num_bones(), 65);
        assert_eq!(creature_187().num_bones(), 187);
        let w = humanoid_from_cmu();
        assert_eq!(w.table.num_mapped(), 24);
        let c = creature_from_humanoid();
        assert!(c.table.num_mapped() > 100, "{}", c.table.num_mapped());
    }
}
