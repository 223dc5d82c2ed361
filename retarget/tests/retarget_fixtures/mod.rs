//! Generated humanoids for retargeting tests: one layout, many ways of building it (postures,
//! proportions, bone axes, names, child order, units, facing), plus a procedural motion.
#![allow(dead_code)]

use glam::{Quat, Vec3};
use rigcast_retarget::mapping::{BoneOptions, MappingTable, SourceRef, TargetEntry};
use rigcast_retarget::{world_transforms, BoneId, Pose, RawSkeleton, Skeleton, Transform};

/// How bone frames are oriented at rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Axes {
    /// Every bone's world rest rotation is identity (BVH style).
    World,
    /// Each bone's local +Y points at its first child, with an extra per-bone roll (glTF /
    /// Blender style).
    AlongBone { roll_rad: f32 },
}

/// Parameters of a generated humanoid.
#[derive(Clone, Debug)]
pub struct Humanoid {
    /// Renames canonical names (e.g. to `mixamorig:` style).
    pub prefix: &'static str,
    pub leg: f32,
    pub arm: f32,
    pub torso: f32,
    /// 0 = T-pose, 45 = A-pose, 90 = arms hanging.
    pub arm_down_deg: f32,
    /// Legs spread outwards (CMU's rest has about 20°).
    pub leg_out_deg: f32,
    pub axes: Axes,
    pub shuffle: bool,
    pub units: f32,
    pub yaw_rad: f32,
    /// 1..=3 spine bones between hips and neck.
    pub spine_bones: usize,
}

impl Default for Humanoid {
    fn default() -> Self {
        Humanoid {
            prefix: "",
            leg: 1.0,
            arm: 1.0,
            torso: 1.0,
            arm_down_deg: 0.0,
            leg_out_deg: 0.0,
            axes: Axes::World,
            shuffle: false,
            units: 1.0,
            yaw_rad: 0.0,
            spine_bones: 2,
        }
    }
}

/// Names of the limb segments compared by the acceptance criteria: (segment, from, to).
pub const LIMB_SEGMENTS: [(&str, &str, &str); 10] = [
    ("l upper arm", "l_upper_arm", "l_forearm"),
    ("l forearm", "l_forearm", "l_hand"),
    ("l thigh", "l_thigh", "l_shin"),
    ("l shin", "l_shin", "l_foot"),
    ("l foot", "l_foot", "l_toe"),
    ("r upper arm", "r_upper_arm", "r_forearm"),
    ("r forearm", "r_forearm", "r_hand"),
    ("r thigh", "r_thigh", "r_shin"),
    ("r shin", "r_shin", "r_foot"),
    ("r foot", "r_foot", "r_toe"),
];

struct Joint {
    name: String,
    parent: Option<usize>,
    position: Vec3,
}

impl Humanoid {
    /// Canonical names of the spine chain, hips first, neck excluded.
    fn spine_names(&self) -> Vec<&'static str> {
        ["spine", "chest", "upper_chest"][..self.spine_bones.clamp(1, 3)].to_vec()
    }

    fn joints(&self) -> Vec<Joint> {
        let mut j: Vec<Joint> = Vec::new();
        let mut add = |name: &str, parent: Option<usize>, position: Vec3| {
            j.push(Joint {
                name: name.to_string(),
                parent,
                position,
            });
            j.len() - 1
        };
        let leg = self.leg;
        let hips_y = 0.05 + 0.87 * leg * self.leg_out_deg.to_radians().cos() + 0.08;
        let hips = add("hips", None, Vec3::new(0.0, hips_y, 0.0));
        // Spine: same total length whatever the number of bones.
        let spine_len = 0.45 * self.torso;
        let names = self.spine_names();
        let mut prev = hips;
        let mut p = Vec3::new(0.0, hips_y + 0.08 * self.torso, -0.01);
        for (k, n) in names.iter().enumerate() {
            prev = add(n, Some(prev), p);
            if k + 1 < names.len() {
                p += Vec3::new(0.0, spine_len / names.len() as f32, 0.005);
            }
        }
        let neck_pos = Vec3::new(0.0, hips_y + 0.08 * self.torso + spine_len, 0.0);
        let top = prev;
        let neck = add("neck", Some(top), neck_pos);
        let head = add(
            "head",
            Some(neck),
            neck_pos + Vec3::new(0.0, 0.1, 0.02) * self.torso,
        );
        add(
            "head_end",
            Some(head),
            neck_pos + Vec3::new(0.0, 0.3, 0.02) * self.torso,
        );
        for (side, sx) in [("l", 1.0f32), ("r", -1.0f32)] {
            let a = self.arm_down_deg.to_radians();
            let d = Vec3::new(sx * a.cos(), -a.sin(), 0.0);
            let clav_pos = neck_pos + Vec3::new(sx * 0.02, -0.04, 0.0);
            let clav = add(&format!("{side}_clavicle"), Some(top), clav_pos);
            let up_pos = clav_pos + Vec3::new(sx * 0.15, 0.0, -0.01);
            let up = add(&format!("{side}_upper_arm"), Some(clav), up_pos);
            let fore_pos = up_pos + d * 0.28 * self.arm;
            let fore = add(&format!("{side}_forearm"), Some(up), fore_pos);
            let hand_pos = fore_pos + d * 0.25 * self.arm;
            let hand = add(&format!("{side}_hand"), Some(fore), hand_pos);
            add(&format!("{side}_hand_end"), Some(hand), hand_pos + d * 0.08);

            let o = self.leg_out_deg.to_radians();
            let ld = Vec3::new(sx * o.sin(), -o.cos(), 0.0);
            let thigh_pos = Vec3::new(sx * 0.1, hips_y - 0.05, 0.0);
            let thigh = add(&format!("{side}_thigh"), Some(hips), thigh_pos);
            let shin_pos = thigh_pos + ld * 0.45 * leg;
            let shin = add(&format!("{side}_shin"), Some(thigh), shin_pos);
            let foot_pos = shin_pos + ld * 0.42 * leg;
            let foot = add(&format!("{side}_foot"), Some(shin), foot_pos);
            let toe_pos = Vec3::new(foot_pos.x, 0.02, foot_pos.z + 0.13);
            let toe = add(&format!("{side}_toe"), Some(foot), toe_pos);
            add(
                &format!("{side}_toe_end"),
                Some(toe),
                toe_pos + Vec3::new(0.0, 0.0, 0.06),
            );
        }
        j
    }

    /// Builds the skeleton.
    pub fn build(&self) -> Skeleton {
        let joints = self.joints();
        let n = joints.len();
        let turn = Quat::from_rotation_y(self.yaw_rad);
        let pos: Vec<Vec3> = joints
            .iter()
            .map(|j| turn * j.position * self.units)
            .collect();
        // World rest rotations.
        let mut world = vec![turn; n];
        if let Axes::AlongBone { roll_rad } = self.axes {
            for i in 0..n {
                let child = (0..n).find(|&c| joints[c].parent == Some(i));
                let dir = match child {
                    Some(c) => (pos[c] - pos[i]).normalize_or_zero(),
                    None => match joints[i].parent {
                        Some(p) => (pos[i] - pos[p]).normalize_or_zero(),
                        None => Vec3::Y,
                    },
                };
                let swing = if dir == Vec3::ZERO {
                    Quat::IDENTITY
                } else {
                    Quat::from_rotation_arc(Vec3::Y, dir)
                };
                world[i] = swing * Quat::from_rotation_y(roll_rad * (1.0 + i as f32 * 0.37));
            }
        }
        let mut raw = RawSkeleton::default();
        let order: Vec<usize> = if self.shuffle {
            (0..n).rev().collect()
        } else {
            (0..n).collect()
        };
        let mut raw_index = vec![0usize; n];
        for (k, &i) in order.iter().enumerate() {
            raw_index[i] = k;
        }
        for &i in &order {
            let j = &joints[i];
            let (t, r) = match j.parent {
                Some(p) => (
                    world[p].inverse() * (pos[i] - pos[p]),
                    world[p].inverse() * world[i],
                ),
                None => (pos[i], world[i]),
            };
            raw.add(
                format!("{}{}", self.prefix, j.name),
                j.parent.map(|p| raw_index[p]),
                Transform {
                    translation: t,
                    rotation: r,
                },
            );
        }
        Skeleton::build(&raw).expect("valid humanoid")
    }

    /// Canonical name of a bone of a skeleton built with this prefix.
    pub fn canonical<'a>(&self, name: &'a str) -> &'a str {
        name.strip_prefix(self.prefix).unwrap_or(name)
    }
}

/// Maps target bones to source bones with the same canonical name.
pub fn table_by_canonical(
    source: &Skeleton,
    source_prefix: &str,
    target: &Skeleton,
    target_prefix: &str,
) -> MappingTable {
    let mut table = MappingTable::empty(target.num_bones());
    for t in target.bone_ids() {
        let canon = target
            .name(t)
            .strip_prefix(target_prefix)
            .unwrap_or(target.name(t));
        if let Some(s) = source.bone(&format!("{source_prefix}{canon}")) {
            table.entries[t.index()] = Some(TargetEntry {
                sources: vec![SourceRef {
                    input: 0,
                    bone: s,
                    weight: 1.0,
                }],
                options: BoneOptions::default(),
                score: 0.0,
                evidence: vec![],
                confidence: 1.0,
            });
        }
    }
    table
}

/// A deterministic walk-like motion: the hips travel forward along the character's facing and
/// bob, every bone swings about its own axis with its own phase, limbs swing widely.
pub fn motion(skel: &Skeleton, num_frames: usize, facing_yaw_rad: f32, units: f32) -> Vec<Pose> {
    let rest = skel.rest_pose();
    let root_y = rest.translations[0].y;
    let forward = Quat::from_rotation_y(facing_yaw_rad) * Vec3::Z;
    (0..num_frames)
        .map(|f| {
            let t = f as f32 / 30.0;
            // Frame 0 is the rest posture standing still; motion fades in over half a second.
            let ramp = (t / 0.5).min(1.0);
            let mut p = rest.clone();
            for b in skel.bone_ids() {
                let k = b.0 as f32;
                let axis = Vec3::new(
                    (k * 1.3).sin(),
                    (k * 0.7).cos(),
                    0.4 + (k * 0.5).sin() * 0.3,
                )
                .normalize_or_zero();
                let amp = if skel.parent(b).is_none() { 0.3 } else { 0.6 };
                let phase = (2.0 * t + k * 0.9).sin() - (k * 0.9).sin();
                let wiggle = Quat::from_axis_angle(axis, ramp * amp * phase);
                p.rotations[b.index()] = rest.rotations[b.index()] * wiggle;
            }
            p.translations[0] = rest.translations[0] + forward * (1.2 * t * units);
            p.translations[0].y = root_y + 0.03 * units * (4.0 * t).sin();
            p
        })
        .collect()
}

/// Standing hip height the generator builds in: hips above the toe joint, legs straight down.
pub fn hip_height(spec: &Humanoid) -> f32 {
    (0.05 + 0.87 * spec.leg + 0.06) * spec.units
}

/// Leg length the generator builds in: thigh (0.45 leg) plus shin (0.42 leg).
pub fn leg_length(spec: &Humanoid) -> f32 {
    0.87 * spec.leg * spec.units
}

/// World joint positions of every bone.
pub fn positions(skel: &Skeleton, pose: &Pose) -> Vec<Vec3> {
    world_transforms(skel, pose)
        .iter()
        .map(|w| w.translation)
        .collect()
}

/// Height of a skeleton's rest (max − min joint y).
pub fn rest_height(skel: &Skeleton) -> f32 {
    let p = positions(skel, &skel.rest_pose());
    let (lo, hi) = p
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v.y), hi.max(v.y))
        });
    hi - lo
}

/// Bone id by canonical name.
pub fn bone(skel: &Skeleton, prefix: &str, canon: &str) -> BoneId {
    skel.bone(&format!("{prefix}{canon}"))
        .unwrap_or_else(|| panic!("no bone {canon}"))
}

/// Angle in degrees between two directions.
pub fn angle_deg(a: Vec3, b: Vec3) -> f32 {
    a.normalize_or_zero()
        .dot(b.normalize_or_zero())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// The standard humanoid driving a shorter-legged one (legs 0.8 ×), mapped by canonical
/// names, and the foot lock between them: the foot-lock tests' pair.
pub fn locked_pair() -> (
    Skeleton,
    Skeleton,
    rigcast_retarget::Mapping,
    rigcast_retarget::footplant::FootLock,
) {
    use rigcast_retarget::analysis::{analyze, SkeletonView};
    use rigcast_retarget::footplant::{FootLock, LockSettings};
    let source = Humanoid::default().build();
    let target = Humanoid {
        leg: 0.8,
        ..Humanoid::default()
    }
    .build();
    let table = table_by_canonical(&source, "", &target, "");
    let opts = rigcast_retarget::RetargetOptions::default();
    let mapping =
        rigcast_retarget::Mapping::build(&[&source], &target, &table, &opts).expect("build");
    let sa = analyze(&SkeletonView::rest(&source));
    let ta = analyze(&SkeletonView::rest(&target));
    let lock =
        FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("a lock for a humanoid");
    (source, target, mapping, lock)
}
