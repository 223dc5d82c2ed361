//! Acceptance (issue 4) on the real CMU walk (`../shared/data/bvh/cmu_131_01_walk.bvh`, skipped
//! when absent): onto an A-pose, glTF-axes variant of its own skeleton and onto Mixamo-, UE- and
//! Rigify-like humanoids, every limb segment's world direction follows the source within 2° mean
//! and 5° max over all frames while naive rotation copying does not; the hips travel the
//! source's displacement scaled by the hip-height ratio within 1%; the feet stand on the
//! target's floor at frame 0 within 1 cm. Also runs the `rigcast retarget` command end to end.

#![allow(clippy::unwrap_used)]

mod common;
#[path = "../../retarget/tests/retarget_fixtures/mod.rs"]
mod retarget_fixtures;

#[path = "common/retarget_cli.rs"]
mod retarget_cli;

use std::path::PathBuf;
use std::sync::Arc;

use glam::{Quat, Vec3};
use retarget_cli::{run, RetargetArgs};
use retarget_fixtures::{angle_deg, hip_height, positions, Axes, Humanoid};
use rigcast_retarget::corpus;
use rigcast_retarget::mapping::{BoneOptions, MappingTable, SourceRef, TargetEntry};
use rigcast_retarget::{Clip, Pose, RawSkeleton, RetargetOptions, Skeleton, Transform};
use rigcast_server::offline::{plan_mapping, retarget_clip};

/// A file of the shared BVH data.
fn data(name: &str) -> Option<PathBuf> {
    common::shared_data(&format!("bvh/{name}"))
}

fn walk() -> Option<Clip> {
    let path = data("cmu_131_01_walk.bvh")?;
    Some(rigcast_sources::load_clip(&path).expect("the CMU walk loads"))
}

/// Limb segments by CMU (3dsMax-friendly) joint names: (segment, from, to).
const CMU_SEGMENTS: [(&str, &str, &str); 10] = [
    ("l upper arm", "LeftShoulder", "LeftElbow"),
    ("l forearm", "LeftElbow", "LeftWrist"),
    ("l thigh", "LeftHip", "LeftKnee"),
    ("l shin", "LeftKnee", "LeftAnkle"),
    ("l foot", "LeftAnkle", "LeftToe"),
    ("r upper arm", "RightShoulder", "RightElbow"),
    ("r forearm", "RightElbow", "RightWrist"),
    ("r thigh", "RightHip", "RightKnee"),
    ("r shin", "RightKnee", "RightAnkle"),
    ("r foot", "RightAnkle", "RightToe"),
];

/// CMU joint → canonical name of the generated humanoids.
const CMU_TO_CANONICAL: [(&str, &str); 25] = [
    ("Hips", "hips"),
    ("Chest", "spine"),
    ("Chest2", "chest"),
    ("Neck", "neck"),
    ("Head", "head"),
    ("Head_end", "head_end"),
    ("LeftCollar", "l_clavicle"),
    ("LeftShoulder", "l_upper_arm"),
    ("LeftElbow", "l_forearm"),
    ("LeftWrist", "l_hand"),
    ("LeftHip", "l_thigh"),
    ("LeftKnee", "l_shin"),
    ("LeftAnkle", "l_foot"),
    ("LeftToe", "l_toe"),
    ("LeftToe_end", "l_toe_end"),
    ("RightCollar", "r_clavicle"),
    ("RightShoulder", "r_upper_arm"),
    ("RightElbow", "r_forearm"),
    ("RightWrist", "r_hand"),
    ("RightHip", "r_thigh"),
    ("RightKnee", "r_shin"),
    ("RightAnkle", "r_foot"),
    ("RightToe", "r_toe"),
    ("RightToe_end", "r_toe_end"),
    ("LFingers", "l_hand_end"),
];

fn entry(bone: rigcast_retarget::BoneId) -> Option<TargetEntry> {
    Some(TargetEntry {
        sources: vec![SourceRef {
            input: 0,
            bone,
            weight: 1.0,
        }],
        options: BoneOptions::default(),
        score: 0.0,
        evidence: vec![],
        confidence: 1.0,
    })
}

/// (target name → source name) pairs as a table.
fn table(source: &Skeleton, target: &Skeleton, pairs: &[(String, String)]) -> MappingTable {
    let mut t = MappingTable::empty(target.num_bones());
    for (tn, sn) in pairs {
        let tb = target
            .bone(tn)
            .unwrap_or_else(|| panic!("target has no {tn}"));
        let sb = source
            .bone(sn)
            .unwrap_or_else(|| panic!("source has no {sn}"));
        t.entries[tb.index()] = entry(sb);
    }
    t
}

/// Naive local-rotation copy through the same table.
fn naive(source: &Skeleton, target: &Skeleton, table: &MappingTable, pose: &Pose) -> Pose {
    let _ = source;
    let mut out = target.rest_pose();
    for t in target.bone_ids() {
        if let Some(e) = table.get(t) {
            out.rotations[t.index()] = pose.rotations[e.sources[0].bone.index()];
        }
    }
    out.translations[0] = pose.translations[0];
    out
}

struct Case<'a> {
    name: &'a str,
    target: Skeleton,
    table: MappingTable,
    /// (segment, target from, target to), parallel to `CMU_SEGMENTS`.
    segments: Vec<(String, String)>,
    hips: String,
    /// Per side (left, right), foot joints as (target joint, CMU joint) pairs.
    feet: [Vec<(String, &'static str)>; 2],
    /// Standing hip height above the toe joints, known from how the target was built.
    hip_height: f32,
}

/// Per segment (mean, max) degrees between source and target directions over all frames.
fn direction_errors(
    clip: &Clip,
    target: &Skeleton,
    poses: &[Pose],
    case: &Case,
) -> Vec<(f32, f32)> {
    let src = &clip.skeleton;
    let mut acc = vec![(0.0f32, 0.0f32); CMU_SEGMENTS.len()];
    for (sp, tp) in clip.poses.iter().zip(poses) {
        let ps = positions(src, sp);
        let pt = positions(target, tp);
        for (k, ((_, a, b), (ta, tb))) in CMU_SEGMENTS.iter().zip(&case.segments).enumerate() {
            let ds = ps[src.bone(b).expect("cmu").index()] - ps[src.bone(a).expect("cmu").index()];
            let dt = pt[target.bone(tb).expect("tgt").index()]
                - pt[target.bone(ta).expect("tgt").index()];
            let e = angle_deg(ds, dt);
            acc[k].0 += e / clip.num_frames() as f32;
            acc[k].1 = acc[k].1.max(e);
        }
    }
    acc
}

fn check(clip: &Clip, case: Case) {
    let out = retarget_clip(
        clip,
        &case.target,
        &case.table,
        &RetargetOptions::default(),
        &mut |_| {},
    )
    .expect("retarget");
    assert_eq!(out.num_frames(), clip.num_frames());
    assert_eq!(out.frame_time_secs, clip.frame_time_secs);
    let errors = direction_errors(clip, &case.target, &out.poses, &case);
    let naive_poses: Vec<Pose> = clip
        .poses
        .iter()
        .map(|p| naive(&clip.skeleton, &case.target, &case.table, p))
        .collect();
    let naive_errors = direction_errors(clip, &case.target, &naive_poses, &case);
    let mut naive_worst = 0.0f32;
    for (((seg, _, _), (mean, max)), (nmean, nmax)) in
        CMU_SEGMENTS.iter().zip(&errors).zip(&naive_errors)
    {
        println!(
            "{}: {seg:12} mean {mean:6.3}° max {max:6.3}°   naive copy: mean {nmean:6.2}° max {nmax:6.2}°",
            case.name
        );
        assert!(
            *mean <= 2.0 && *max <= 5.0,
            "{}: {seg}: mean {mean}° max {max}°",
            case.name
        );
        naive_worst = naive_worst.max(*nmax);
    }
    assert!(
        naive_worst > 10.0,
        "{}: naive copy unexpectedly within {naive_worst}°",
        case.name
    );

    // Root: independent hip heights — source: a straightened CMU leg from the file's own
    // offsets (hip-offset drop + thigh + shin + ankle-to-toe drop, both legs averaged), since
    // CMU's rest spreads the legs; target: as built.
    let src = &clip.skeleton;
    // Strides scale with the legs: thigh + shin, measured on both rests from the joints the
    // segments name (not from the mapping).
    let leg = |skel: &Skeleton, joints: [(&str, &str); 4]| {
        let rest = positions(skel, &skel.rest_pose());
        let at = |n: &str| rest[skel.bone(n).expect("leg joint").index()];
        joints
            .iter()
            .map(|(a, b)| (at(b) - at(a)).length())
            .sum::<f32>()
            / 2.0
    };
    let t = |i: usize| (case.segments[i].0.as_str(), case.segments[i].1.as_str());
    let c = |i: usize| (CMU_SEGMENTS[i].1, CMU_SEGMENTS[i].2);
    let ratio = leg(&case.target, [t(2), t(3), t(7), t(8)]) / leg(src, [c(2), c(3), c(7), c(8)]);
    let hs = src.bone("Hips").expect("hips").index();
    let ht = case.target.bone(&case.hips).expect("hips").index();
    let s0 = positions(src, &clip.poses[0])[hs];
    let t0 = positions(&case.target, &out.poses[0])[ht];
    let mut worst = 0.0f32;
    for f in (1..clip.num_frames()).step_by(7) {
        let ds = positions(src, &clip.poses[f])[hs] - s0;
        let dt = positions(&case.target, &out.poses[f])[ht] - t0;
        if ds.length() < 0.2 {
            continue; // relative error of tiny moves is noise
        }
        worst = worst.max((dt - ds * ratio).length() / (ds * ratio).length());
    }
    let last = clip.num_frames() - 1;
    let travel = (positions(src, &clip.poses[last])[hs] - s0).length();
    println!(
        "{}: source hips travel {travel:.3} m, leg-length ratio {ratio:.4}, worst relative displacement error {worst:.4}",
        case.name
    );
    assert!(travel > 1.0, "the walk travels");
    assert!(
        worst < 0.01,
        "{}: hips displacement off by {:.2}%",
        case.name,
        worst * 100.0
    );

    // Feet at frame 0: each foot's lowest joint (toe or toe tip) stands as high above the
    // target's floor as the source's stands above the source's floor, scaled. Source floor:
    // how low those joints get over the clip, as the 5th percentile of the frames' lowest (a
    // toe dipping lower for a frame or two is not the floor); target floor: its rest (a
    // character authored on the ground), or for a rest floating at the origin, the source's
    // floor scaled.
    let mut lows: Vec<f32> = clip
        .poses
        .iter()
        .map(|p| {
            let ps = positions(src, p);
            (case.feet.iter().flatten())
                .map(|(_, n)| ps[src.bone(n).expect("toe").index()].y)
                .fold(f32::INFINITY, f32::min)
        })
        .collect();
    lows.sort_by(f32::total_cmp);
    let src_floor = lows[lows.len() / 20];
    let rest = positions(&case.target, &case.target.rest_pose());
    let first = positions(&case.target, &out.poses[0]);
    let src_first = positions(src, &clip.poses[0]);
    let rest_floor = case
        .feet
        .iter()
        .flatten()
        .map(|(n, _)| rest[case.target.bone(n).expect("toe").index()].y)
        .fold(f32::INFINITY, f32::min);
    let floor_t = if rest_floor.abs() < 0.2 {
        rest_floor
    } else {
        ratio * src_floor
    };
    // The standing foot (the source's lowest) must be exact: the hips' height is calibrated on
    // it; a lifted foot bends with the target's own proportions, so it may differ a little.
    let src_low = |side: &Vec<(String, &'static str)>| {
        side.iter()
            .map(|(_, n)| src_first[src.bone(n).expect("toe").index()].y)
            .fold(f32::INFINITY, f32::min)
    };
    let standing = case.feet.iter().map(src_low).fold(f32::INFINITY, f32::min);
    for side in &case.feet {
        let bound = if src_low(side) <= standing + 0.02 {
            0.01
        } else {
            0.03
        };
        let low_t = side
            .iter()
            .map(|(n, _)| first[case.target.bone(n).expect("toe").index()].y)
            .fold(f32::INFINITY, f32::min);
        let low_s = side
            .iter()
            .map(|(_, n)| src_first[src.bone(n).expect("toe").index()].y)
            .fold(f32::INFINITY, f32::min);
        let expected = floor_t + ratio * (low_s - src_floor);
        let err = (low_t - expected).abs();
        println!(
            "{}: {} at frame 0: {:.2} cm above its floor, expected {:.2} cm (error {:.2} cm)",
            case.name,
            side[0].0,
            (low_t - floor_t) * 100.0,
            (expected - floor_t) * 100.0,
            err * 100.0
        );
        assert!(
            err < bound,
            "{}: {} is {err} m off at frame 0",
            case.name,
            side[0].0
        );
    }
}

/// Per side, the CMU foot joints whose lowest touches the floor.
const CMU_FEET: [[&str; 2]; 2] = [["LeftToe", "LeftToe_end"], ["RightToe", "RightToe_end"]];

/// Foot pairs for a target with the same foot joints as CMU under other names.
fn feet_like_cmu(names: impl Fn(&str) -> String) -> [Vec<(String, &'static str)>; 2] {
    CMU_FEET.map(|side| side.iter().map(|&n| (names(n), n)).collect())
}

/// Straight-leg hip height of a CMU skeleton from its offsets, both legs averaged.
fn cmu_hip_height(src: &Skeleton) -> f32 {
    let off = |n: &str| src.rest()[src.bone(n).expect("cmu joint").index()].translation;
    let leg = |side: &str| {
        off(&format!("{side}Hip")).y.abs()
            + off(&format!("{side}Knee")).length()
            + off(&format!("{side}Ankle")).length()
            + off(&format!("{side}Toe")).y.abs()
    };
    (leg("Left") + leg("Right")) / 2.0
}

/// CMU's own skeleton re-posed: arms raised from hanging to 45° (an A-pose), legs brought
/// together under the hips, and every bone's local axes turned to point along the bone (glTF
/// style), names unchanged.
fn a_pose_variant(src: &Skeleton) -> Skeleton {
    let rest = positions(src, &src.rest_pose());
    let mut pos = rest.clone();
    let below = |root: &str| -> Vec<usize> {
        let r = src.bone(root).expect("joint");
        src.bone_ids()
            .filter(|&b| {
                let mut x = Some(b);
                while let Some(y) = x {
                    if y == r {
                        return b != r;
                    }
                    x = src.parent(y);
                }
                false
            })
            .map(|b| b.index())
            .collect()
    };
    for (root, angle) in [("LeftShoulder", 45f32), ("RightShoulder", -45.0)] {
        let pivot = rest[src.bone(root).expect("joint").index()];
        for i in below(root) {
            pos[i] = pivot + Quat::from_rotation_z(angle.to_radians()) * (rest[i] - pivot);
        }
    }
    let mut raw = RawSkeleton::default();
    let world: Vec<Quat> = src
        .bone_ids()
        .map(|b| {
            let child = src
                .children(b)
                .iter()
                .find(|c| (pos[c.index()] - pos[b.index()]).length() > 1e-6);
            match child {
                Some(c) => Quat::from_rotation_arc(
                    Vec3::Y,
                    (pos[c.index()] - pos[b.index()]).normalize_or_zero(),
                ),
                None => Quat::IDENTITY,
            }
        })
        .collect();
    for b in src.bone_ids() {
        let i = b.index();
        let rest = match src.parent(b) {
            Some(p) => Transform {
                translation: world[p.index()].inverse() * (pos[i] - pos[p.index()]),
                rotation: world[p.index()].inverse() * world[i],
            },
            None => Transform {
                translation: pos[i],
                rotation: world[i],
            },
        };
        raw.add(src.name(b), src.parent(b).map(|p| p.index()), rest);
    }
    Skeleton::build(&raw).expect("variant")
}

#[test]
fn cmu_walk_onto_an_a_pose_variant_of_itself() {
    let Some(clip) = walk() else { return };
    let target = a_pose_variant(&clip.skeleton);
    let table = MappingTable::by_exact_name(&clip.skeleton, &target);
    // Same legs: the hip-height ratio is 1 by construction.
    let standing = cmu_hip_height(&clip.skeleton);
    check(
        &clip,
        Case {
            name: "CMU→A-pose CMU",
            segments: CMU_SEGMENTS
                .iter()
                .map(|(_, a, b)| (a.to_string(), b.to_string()))
                .collect(),
            hips: "Hips".into(),
            feet: feet_like_cmu(|n: &str| n.to_string()),
            hip_height: standing,
            target,
            table,
        },
    );
}

fn humanoid_case<'a>(name: &'a str, clip: &Clip, spec: Humanoid) -> Case<'a> {
    let target = spec.build();
    let pairs: Vec<(String, String)> = CMU_TO_CANONICAL
        .iter()
        .map(|(s, t)| (format!("{}{t}", spec.prefix), s.to_string()))
        .collect();
    let table = table(&clip.skeleton, &target, &pairs);
    let canon = |n: &str| -> String {
        let c = CMU_TO_CANONICAL
            .iter()
            .find(|(s, _)| *s == n)
            .expect("segment joint")
            .1;
        format!("{}{c}", spec.prefix)
    };
    Case {
        name,
        segments: CMU_SEGMENTS
            .iter()
            .map(|(_, a, b)| (canon(a), canon(b)))
            .collect(),
        hips: format!("{}hips", spec.prefix),
        feet: feet_like_cmu(canon),
        hip_height: hip_height(&spec),
        target,
        table,
    }
}

#[test]
fn cmu_walk_onto_generated_humanoids_of_other_proportions_and_units() {
    let Some(clip) = walk() else { return };
    let mixamo = Humanoid {
        prefix: "mixamorig:",
        arm_down_deg: 0.0,
        axes: Axes::AlongBone { roll_rad: 0.0 },
        spine_bones: 3,
        ..Humanoid::default()
    };
    let ue = Humanoid {
        prefix: "ue_",
        arm_down_deg: 45.0,
        leg: 1.1,
        arm: 1.1,
        axes: Axes::AlongBone { roll_rad: 1.57 },
        units: 100.0,
        ..Humanoid::default()
    };
    let rigify = Humanoid {
        prefix: "DEF-",
        arm_down_deg: 35.0,
        leg: 0.85,
        torso: 1.2,
        axes: Axes::AlongBone { roll_rad: -0.4 },
        shuffle: true,
        ..Humanoid::default()
    };
    for (name, spec) in [
        ("CMU→Mixamo-like", mixamo),
        ("CMU→UE-like (cm)", ue),
        ("CMU→Rigify-like", rigify),
    ] {
        let units = spec.units;
        check_scaled(&clip, humanoid_case(name, &clip, spec), units);
    }
}

/// `check` for targets in other units (positions divided by `units` before the cm check).
fn check_scaled(clip: &Clip, case: Case, units: f32) {
    if units == 1.0 {
        check(clip, case);
        return;
    }
    // Scale the target back to metres by building a metre copy: retargeting results must not
    // depend on the target's units, so run the metre copy through the same checks and compare
    // the two outputs.
    let metres = {
        let raw = case.target.to_raw();
        let mut raw = raw;
        for b in &mut raw.bones {
            b.rest.translation /= units;
        }
        Skeleton::build(&raw).expect("metre copy")
    };
    let out_units = retarget_clip(
        clip,
        &case.target,
        &case.table,
        &RetargetOptions::default(),
        &mut |_| {},
    )
    .expect("retarget");
    let out_m = retarget_clip(
        clip,
        &metres,
        &case.table,
        &RetargetOptions::default(),
        &mut |_| {},
    )
    .expect("retarget");
    for (pu, pm) in out_units.poses.iter().zip(&out_m.poses).step_by(50) {
        let a = positions(&case.target, pu);
        let b = positions(&metres, pm);
        for (x, y) in a.iter().zip(&b) {
            assert!(
                (*x / units - *y).length() < 1e-4,
                "units change the result: {x} vs {y}"
            );
        }
    }
    check(
        clip,
        Case {
            target: metres,
            hip_height: case.hip_height / units,
            ..case
        },
    );
}

#[test]
fn retarget_command_writes_the_target_skeleton() {
    let Some(anim) = data("cmu_131_01_walk.bvh") else {
        return;
    };
    let clip = rigcast_sources::load_clip(&anim).expect("load");
    let dir = std::env::temp_dir().join(format!("rigcast-retarget-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp");
    // Target: the A-pose variant saved as BVH (BVH cannot hold rest rotations, so save the
    // variant's joint layout with identity axes by converting through a clip of its rest).
    let variant = a_pose_variant(&clip.skeleton);
    let target_path = dir.join("target.bvh");
    let rest_clip = Clip::new(
        "target",
        Arc::new(variant.clone()),
        vec![variant.rest_pose()],
        1.0 / 30.0,
    )
    .expect("clip");
    rigcast_sources::save_clip(&target_path, &rest_clip).expect("save target");
    let out_path = dir.join("out.bvh");
    run(&RetargetArgs {
        anim: anim.clone(),
        target: target_path.clone(),
        output: out_path.clone(),
        mapping: None,
        fps: Some(30.0),
        in_place: false,
        no_foot_lock: false,
    })
    .expect("retarget command");
    let out = rigcast_sources::load_clip(&out_path).expect("output loads");
    let target = rigcast_sources::load_clip(&target_path)
        .expect("target loads")
        .skeleton;
    assert_eq!(out.skeleton.names(), target.names());
    assert!((out.frame_time_secs - 1.0 / 30.0).abs() < 1e-6);
    let expected =
        ((clip.num_frames() - 1) as f64 * clip.frame_time_secs * 30.0 + 1e-9).floor() as usize + 1;
    assert_eq!(out.num_frames(), expected);
    // A mapping file overrides the automatic mapping: an unmapped bone is held at rest.
    let mapping_path = dir.join("overrides.toml");
    std::fs::write(
        &mapping_path,
        "version = 1\n[bones.\"LeftWrist\"]\nunmapped = true\n",
    )
    .expect("write overrides");
    let held_path = dir.join("held.bvh");
    run(&RetargetArgs {
        anim: anim.clone(),
        target: target_path.clone(),
        output: held_path.clone(),
        mapping: Some(mapping_path),
        fps: None,
        in_place: true,
        no_foot_lock: false,
    })
    .expect("retarget with overrides");
    let held = rigcast_sources::load_clip(&held_path).expect("output loads");
    assert_eq!(held.num_frames(), clip.num_frames());
    let wrist = held.skeleton.bone("LeftWrist").expect("wrist").index();
    let rest = held.skeleton.rest()[wrist].rotation;
    for p in &held.poses {
        assert!(rigcast_retarget::approx::quat_close(
            p.rotations[wrist],
            rest,
            1e-3
        ));
    }
    // In place: the hips stay over one spot.
    let hips = held.skeleton.bone("Hips").expect("hips").index();
    let first = held.poses[0].translations[hips];
    for p in &held.poses {
        let d = p.translations[hips] - first;
        assert!(Vec3::new(d.x, 0.0, d.z).length() < 1e-3, "hips moved {d}");
    }
    let bad_mapping = dir.join("bad.toml");
    std::fs::write(
        &bad_mapping,
        "version = 1\n[bones.\"NoSuchBone\"]\nsource = \"Hips\"\n",
    )
    .expect("write");
    let err = run(&RetargetArgs {
        anim: anim.clone(),
        target: target_path.clone(),
        output: dir.join("y.bvh"),
        mapping: Some(bad_mapping),
        fps: None,
        in_place: false,
        no_foot_lock: false,
    })
    .expect_err("unknown bone in the mapping file");
    assert!(format!("{err:#}").contains("NoSuchBone"), "{err:#}");
    // Bad input is a clear error, not a panic.
    let err = run(&RetargetArgs {
        anim: dir.join("missing.bvh"),
        target: target_path,
        output: dir.join("x.bvh"),
        mapping: None,
        fps: None,
        in_place: false,
        no_foot_lock: false,
    })
    .expect_err("missing file");
    assert!(format!("{err:#}").contains("missing.bvh"), "{err:#}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The acceptance targets proper: the corpus's Mixamo-, UE- and Rigify-like humanoids (with
/// fingers, twist and helper bones) in T-pose and A-pose, mapped by the automatic mapper.
#[test]
fn cmu_walk_onto_corpus_mixamo_ue_rigify_t_and_a_poses() {
    let Some(clip) = walk() else { return };
    for name in [
        "mixamo",
        "mixamo_apose",
        "unreal",
        "unreal_apose",
        "rigify",
        "rigify_apose",
    ] {
        let entry = corpus::get(name).unwrap_or_else(|| panic!("corpus has {name}"));
        let target = entry.skeleton.clone();
        let by_label = |label: &str| -> Option<String> {
            target
                .bone_ids()
                .find(|b| entry.labels[b.index()] == label)
                .map(|b| target.name(b).to_string())
        };
        let need = |label: &str| by_label(label).unwrap_or_else(|| panic!("{name}: no {label}"));
        let target_clip =
            Clip::new(name, Arc::new(target.clone()), vec![], 1.0 / 30.0).expect("clip");
        let plan = plan_mapping(&clip, &target_clip, None).expect("automatic mapping");
        let mut segments = Vec::new();
        for side in ["left", "right"] {
            for (a, b) in [
                ("upper_arm", "lower_arm"),
                ("lower_arm", "hand"),
                ("upper_leg", "lower_leg"),
                ("lower_leg", "foot"),
                ("foot", "toes"),
            ] {
                segments.push((need(&format!("{side}_{a}")), need(&format!("{side}_{b}"))));
            }
        }
        // CMU_SEGMENTS lists left then right in the same order.
        let rest = positions(&target, &target.rest_pose());
        let y = |n: &str| rest[target.bone(n).expect("bone").index()].y;
        let (lt, rt) = (need("left_toes"), need("right_toes"));
        let hip_height = y(&need("hips")) - (y(&lt) + y(&rt)) / 2.0;
        let side_feet = |side: &str, cmu: [&'static str; 2]| {
            let mut v = vec![(need(&format!("{side}_toes")), cmu[0])];
            if let Some(end) = by_label(&format!("{side}_toe_end")) {
                v.push((end, cmu[1]));
            }
            v
        };
        check(
            &clip,
            Case {
                name,
                segments,
                hips: need("hips"),
                feet: [
                    side_feet("left", CMU_FEET[0]),
                    side_feet("right", CMU_FEET[1]),
                ],
                hip_height,
                target,
                table: plan.table,
            },
        );
    }
}

/// The whole offline path on real files with different conventions, mapped by the automatic
/// mapper: every limb segment of the target follows the source segment between the joints its
/// ends are mapped to.
#[test]
fn cmu_walk_onto_other_files_with_the_automatic_mapper() {
    let Some(clip) = walk() else { return };
    let targets: [(&str, [(&str, &str); 10]); 2] = [
        (
            "cmu_31joint_example.bvh",
            [
                ("LeftArm", "LeftForeArm"),
                ("LeftForeArm", "LeftHand"),
                ("LeftUpLeg", "LeftLeg"),
                ("LeftLeg", "LeftFoot"),
                ("LeftFoot", "LeftToeBase"),
                ("RightArm", "RightForeArm"),
                ("RightForeArm", "RightHand"),
                ("RightUpLeg", "RightLeg"),
                ("RightLeg", "RightFoot"),
                ("RightFoot", "RightToeBase"),
            ],
        ),
        (
            "cmu_run.bvh",
            [
                ("lShldr", "lForeArm"),
                ("lForeArm", "lHand"),
                ("lThigh", "lShin"),
                ("lShin", "lFoot"),
                ("lFoot", "lFoot_end"),
                ("rShldr", "rForeArm"),
                ("rForeArm", "rHand"),
                ("rThigh", "rShin"),
                ("rShin", "rFoot"),
                ("rFoot", "rFoot_end"),
            ],
        ),
    ];
    for (file, segments) in targets {
        let Some(path) = data(file) else { continue };
        let target_clip = rigcast_sources::load_clip(&path).expect("target loads");
        let plan = rigcast_server::offline::plan_mapping(&clip, &target_clip, None).expect("plan");
        let target = &*target_clip.skeleton;
        let opts = RetargetOptions {
            source_reference: vec![plan.source_reference.clone()],
            target_reference: plan.target_reference.clone(),
            ..RetargetOptions::default()
        };
        let out = retarget_clip(&clip, target, &plan.table, &opts, &mut |_| {}).expect("retarget");
        let src = &clip.skeleton;
        let mapped = |n: &str| {
            let t = target
                .bone(n)
                .unwrap_or_else(|| panic!("{file} has no {n}"));
            plan.table
                .get(t)
                .and_then(|e| e.primary())
                .map(|s| s.bone)
                .unwrap_or_else(|| panic!("{file}: {n} is not mapped"))
        };
        for (a, b) in segments {
            let (sa, sb) = (mapped(a), mapped(b));
            let (ta, tb) = (target.bone(a).expect("a"), target.bone(b).expect("b"));
            let (mut sum, mut max) = (0.0f32, 0.0f32);
            for (sp, tp) in clip.poses.iter().zip(&out.poses) {
                let ps = positions(src, sp);
                let pt = positions(target, tp);
                let e = angle_deg(
                    ps[sb.index()] - ps[sa.index()],
                    pt[tb.index()] - pt[ta.index()],
                );
                sum += e;
                max = max.max(e);
            }
            let mean = sum / clip.num_frames() as f32;
            println!(
                "{file}: {a}→{b} (from {}→{}): mean {mean:.3}° max {max:.3}°",
                src.name(sa),
                src.name(sb)
            );
            assert!(
                mean <= 2.0 && max <= 5.0,
                "{file}: {a}→{b}: mean {mean}° max {max}°"
            );
        }
    }
}
