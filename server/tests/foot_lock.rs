//! Foot locking judged on real data (issue 13): the CMU 131_01 walk retargeted offline onto
//! four characters with different leg lengths (the built-in mannequin, Mixamo's X Bot,
//! Quaternius' Casual, and the short-legged Godot platformer robot), and the first labelled
//! walk onto every labelled human rig, with and without the lock. Measured in world space
//! on the output, with the plants detected on the source:
//! - horizontal drift of the joint the target's foot stands on (of its heel and ball joints,
//!   the one nearest the floor on the frame before) between consecutive frames of a plant
//!   (mean, cm/frame): ≤ 0.05 with the lock, and under a third of the figure without it. The
//!   drift of every heel and ball joint is printed beside it, not judged: a pinned foot turns
//!   with the performer's about the joint it stands on, and a turn moves its other end by the
//!   turn times the foot's length (issue 35 judges the standing contact so, as
//!   `retarget_quality`'s locked_legs does);
//! - no heel or ball joint below the floor by more than 0.5 cm (the floor and each joint's
//!   standing height are read from the character's own rest, authored standing on y = 0);
//! - no knee flip: wherever a knee is bent, its bend axis in the thigh's frame has the sign
//!   it has in the unlocked output.
//!
//! Skips with a printed reason when the shared data is absent.
#![allow(clippy::unwrap_used)]

mod common;

use std::collections::HashMap;
use std::sync::Arc;

use glam::Vec3;
use rigcast_retarget::footplant::{
    detect_clip, find_legs, FootLock, Leg, LockSettings, PlantSettings, PlantTrack,
};
use rigcast_retarget::{world_transforms, Clip, Mapping, RetargetOptions, WorldTransform};
use rigcast_server::offline::plan_mapping;

/// Half the standing height of the 1.75 m body the floor is judged in (a hip joint's height).
const LEG_OF_175_CM_BODY: f32 = 0.875;

/// Figures of one output.
#[derive(Debug, Clone, Copy)]
struct Quality {
    /// Drift of the joint each planted foot stands on (judged).
    contact_drift_cm_per_frame: f64,
    /// Drift of every heel and ball joint of a planted foot (printed).
    drift_cm_per_frame: f64,
    /// 90th percentile, over planted frames, of how far the foot's lowest contact joint is
    /// from its standing height (cm of a 1.75 m body, as issue 35 judges the floor: the lock
    /// holds a pinned foot above it by the source's clearance, scaled to the legs).
    planted_off_standing_cm: f32,
    deepest_below_floor_cm: f32,
    knee_flips: usize,
    /// Largest change of a heel or ball joint's per-frame move (its second difference): a
    /// pop shows here as a spike, a smooth swing does not.
    largest_kick_cm: f32,
    /// The frame of the largest kick.
    largest_kick_frame: usize,
}

/// Each leg's knee bend axis in its thigh's frame, averaged over the strongly bent frames of
/// a (free) output: the reference a flip would reverse.
fn bend_axes(out: &Clip, legs: &[(Leg, usize)]) -> HashMap<usize, Vec3> {
    let mut axes = HashMap::new();
    for p in &out.poses {
        let w = world_transforms(&out.skeleton, p);
        for (leg, _) in legs {
            let t = |b: rigcast_retarget::BoneId| w[b.index()].translation;
            let (hip, knee, ankle) = (t(leg.upper), t(leg.lower), t(leg.foot));
            if (knee - hip).angle_between(ankle - knee).to_degrees() > 20.0 {
                let n = (knee - hip).cross(ankle - knee).normalize_or_zero();
                *axes.entry(leg.upper.index()).or_insert(Vec3::ZERO) +=
                    w[leg.upper.index()].rotation.inverse() * n;
            }
        }
    }
    axes
}

fn measure(
    out: &Clip,
    legs: &[(Leg, usize)],
    plants: &PlantTrack,
    near: f32,
    rest: &[WorldTransform],
    bend_axes: &HashMap<usize, Vec3>,
) -> Quality {
    let flat = |v: Vec3| Vec3::new(v.x, 0.0, v.z);
    let worlds: Vec<Vec<WorldTransform>> = out
        .poses
        .iter()
        .map(|p| world_transforms(&out.skeleton, p))
        .collect();
    let (mut sum, mut n) = (0.0f64, 0usize);
    let (mut contact_sum, mut contact_n) = (0.0f64, 0usize);
    let mut deepest = f32::NEG_INFINITY;
    let mut flips = 0;
    let mut largest_kick: f32 = 0.0;
    let mut largest_kick_frame = 0;
    let mut hover = Vec::new();
    for &(leg, src) in legs {
        let joints: Vec<_> = [Some(leg.foot), leg.toes].into_iter().flatten().collect();
        for f in 0..out.num_frames() {
            let w = &worlds[f];
            let p = |b: rigcast_retarget::BoneId| w[b.index()].translation;
            for &j in &joints {
                deepest = deepest.max(rest[j.index()].translation.y - p(j).y);
                if f > 1 {
                    let (a, b) = (
                        worlds[f - 1][j.index()].translation,
                        worlds[f - 2][j.index()].translation,
                    );
                    let kick = (p(j) - 2.0 * a + b).length() * 100.0;
                    if kick > largest_kick {
                        (largest_kick, largest_kick_frame) = (kick, f);
                    }
                }
                if f > 0 && plants.is_planted(f, src) && plants.is_planted(f - 1, src) {
                    let before = worlds[f - 1][j.index()].translation;
                    sum += f64::from(flat(p(j) - before).length()) * 100.0;
                    n += 1;
                }
            }
            if f > 0 && plants.is_planted(f, src) && plants.is_planted(f - 1, src) {
                // The joint the foot stands on: the one nearest the floor on the frame before.
                let was = |j: &rigcast_retarget::BoneId| worlds[f - 1][j.index()].translation;
                if let Some(j) = joints.iter().min_by(|a, b| was(a).y.total_cmp(&was(b).y)) {
                    contact_sum += f64::from(flat(p(*j) - was(j)).length()) * 100.0;
                    contact_n += 1;
                }
            }
            // Planted, the foot's lowest contact stands at its standing height, where the
            // source's matching contact stands on its ground: its lowest for a foot with toes,
            // its heel for one without (at a toe-off the performer's heel rises, and a foot
            // whose toes are not rigged rises on them with it).
            let source_contact = if leg.toes.is_some() {
                plants.lifts(f)
            } else {
                plants.heel_lifts(f)
            };
            let down = source_contact.get(src).is_some_and(|h| *h < near);
            if f > 0 && down && plants.is_planted(f, src) && plants.is_planted(f - 1, src) {
                let gap = joints
                    .iter()
                    .map(|j| p(*j).y - rest[j.index()].translation.y)
                    .fold(f32::INFINITY, f32::min);
                hover.push(gap.abs() * 100.0);
            }
            // The knee's bend axis in the thigh's own frame keeps its sign (a hinge).
            let (hip, knee, ankle) = (p(leg.upper), p(leg.lower), p(leg.foot));
            let normal = (knee - hip).cross(ankle - knee);
            let bent = (knee - hip).angle_between(ankle - knee).to_degrees() > 10.0;
            let axis = w[leg.upper.index()].rotation.inverse() * normal;
            if bent && axis.dot(bend_axes[&leg.upper.index()]) < 0.0 {
                flips += 1;
            }
        }
    }
    hover.sort_by(f32::total_cmp);
    let leg = legs.iter().map(|(l, _)| l.length).sum::<f32>() / legs.len().max(1) as f32;
    let body = LEG_OF_175_CM_BODY / leg.max(1e-6);
    Quality {
        planted_off_standing_cm: hover.get(hover.len() * 9 / 10).copied().unwrap_or(0.0) * body,
        contact_drift_cm_per_frame: contact_sum / contact_n.max(1) as f64,
        drift_cm_per_frame: sum / n.max(1) as f64,
        deepest_below_floor_cm: deepest * 100.0,
        knee_flips: flips,
        largest_kick_cm: largest_kick,
        largest_kick_frame,
    }
}

/// A source contact lower than this above its ground stands on it: 1 cm of a 1.75 m body, in
/// the source's units (its legs `source_legs`), as issue 35 judges the floor.
fn near_ground(source_legs: &[Leg]) -> f32 {
    let leg = source_legs.iter().map(|l| l.length).sum::<f32>() / source_legs.len().max(1) as f32;
    0.01 * leg / LEG_OF_175_CM_BODY
}

/// The built-in mannequin, at rest, as a target.
fn mannequin_target() -> (String, Clip) {
    let mannequin = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let rest = vec![mannequin.rest_pose()];
    let clip = Clip::new("mannequin", mannequin, rest, 1.0 / 30.0).unwrap();
    ("builtin:mannequin".into(), clip)
}

/// The offline lock's figures for `source` onto each of `targets` (see the module's doc),
/// every target judged before the test fails; their legs differ in length by 30 % or more.
fn feet_stay_planted(source: &Clip, targets: &[(String, Clip)]) {
    let mut lengths = Vec::new();
    let mut failures = Vec::new();
    for (name, target) in targets {
        let plan = plan_mapping(&source, target, None).unwrap();
        let source_legs = find_legs(&source.skeleton, &plan.source_analysis);
        let plants = detect_clip(
            &source.skeleton,
            &source_legs,
            &source.poses,
            source.frame_time_secs as f32,
            plan.source_up,
            &PlantSettings::default(),
        );
        let legs: Vec<(Leg, usize)> = find_legs(&target.skeleton, &plan.target_analysis)
            .into_iter()
            .filter_map(|l| Some((l, source_legs.iter().position(|s| s.key() == l.key())?)))
            .collect();
        if legs.len() != 2 {
            failures.push(format!(
                "{name}: {} legs paired with the source's",
                legs.len()
            ));
            continue;
        }
        let rest = world_transforms(&target.skeleton, &target.skeleton.rest_pose());
        let free_clip = common::retarget(&source, &plan, target, false);
        let axes = bend_axes(&free_clip, &legs);
        let near = near_ground(&source_legs);
        let free = measure(&free_clip, &legs, &plants, near, &rest, &axes);
        let locked = measure(
            &common::retarget(&source, &plan, target, true),
            &legs,
            &plants,
            near,
            &rest,
            &axes,
        );
        println!(
            "{name}: leg {:.3} m; drift {:.4} cm/frame locked, {:.4} free (every foot joint: \
             {:.4} locked, {:.4} free); lowest below floor {:.2} cm locked, {:.2} free; knee \
             flips {} locked, {} free; largest foot kick {:.2} cm/frame² locked (frame {}, \
             plants around it {}), {:.2} free",
            legs[0].0.length,
            locked.contact_drift_cm_per_frame,
            free.contact_drift_cm_per_frame,
            locked.drift_cm_per_frame,
            free.drift_cm_per_frame,
            locked.deepest_below_floor_cm,
            free.deepest_below_floor_cm,
            locked.knee_flips,
            free.knee_flips,
            locked.largest_kick_cm,
            locked.largest_kick_frame,
            (locked.largest_kick_frame.saturating_sub(12)..locked.largest_kick_frame + 3)
                .filter(|f| *f < plants.num_frames())
                .map(|f| {
                    (0..plants.legs.len())
                        .map(|l| if plants.is_planted(f, l) { 'P' } else { '.' })
                        .collect::<String>()
                })
                .collect::<Vec<_>>()
                .join(" "),
            free.largest_kick_cm,
        );
        lengths.push(legs[0].0.length);
        println!(
            "{name}: planted feet off their standing height {:.2} cm locked, {:.2} free (90th pct)",
            locked.planted_off_standing_cm, free.planted_off_standing_cm
        );
        let checks = [
            ("drift", locked.contact_drift_cm_per_frame <= 0.05),
            (
                "drift not a third of the free one",
                locked.contact_drift_cm_per_frame * 3.0 < free.contact_drift_cm_per_frame,
            ),
            ("below the floor", locked.deepest_below_floor_cm <= 0.5),
            // Measured (cm of a 1.75 m body): mannequin 0.70, X Bot 0.70, Casual 0.83, Godot
            // robot 0.98, UE-style mannequin 0.72, RobotExpressive 0.96 (free 3.2 / 6.6 /
            // 5.8 / 20.6 / 7.6 / 11.6): a pinned foot follows the source's clearance above its
            // ground, up to 0.8 % of the leg, and its heel the source's above its toe, up to
            // 2 %; a foot without toes rises with the source's heel. Judged where the source's
            // matching contact stands within 1 cm of its ground (before, on every planted
            // frame: 0.71, 0.71, 0.80, 0.96, 0.75, 0.75, with the toeless feet held down at a
            // toe-off; judged so, they read 3.4 on the three toeless rigs now). In cm of each rig's own size, as judged before: mannequin 0.75, X Bot 0.73,
            // Casual 0.90, Godot robot 0.62, RobotExpressive 1.33 (its legs are 1.54 m). Before
            // the animation was fitted to the standing posture first: X Bot 2.18; before the
            // landing settle the mannequin's was 4.66.
            ("off standing", locked.planted_off_standing_cm <= 1.0),
            ("knee flips", locked.knee_flips == 0),
            // Locks blend in and out: no foot changes speed from one frame to the next much
            // more than in the animation itself.
            ("kick", locked.largest_kick_cm <= 1.5 * free.largest_kick_cm),
        ];
        for (what, ok) in checks {
            if !ok {
                failures.push(format!("{name}: {what}: {locked:?} vs {free:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // Different leg lengths, as the acceptance asks.
    lengths.sort_by(f32::total_cmp);
    assert!(
        lengths[lengths.len() - 1] > 1.3 * lengths[0],
        "leg lengths {lengths:?}"
    );
}

#[test]
fn cmu_walk_feet_stay_planted_on_four_characters() {
    let Some(source) = common::shared_clip(common::CMU_WALK) else {
        return;
    };
    let mut targets = vec![mannequin_target()];
    for rel in [
        "zoo/gltf/mixamo_gltf__Xbot.glb",
        "zoo/gltf/quaternius_humanoid__Casual.glb",
        "zoo/gltf/godot_robot__platformer_player.glb",
    ] {
        let Some(p) = common::shared_data(rel) else {
            return;
        };
        targets.push((rel.into(), rigcast_sources::load_rig(&p).unwrap().0));
    }
    feet_stay_planted(&source, &targets);
}

/// The same, with the data discovered: the first labelled walk (found by its motion; two
/// retargets of a whole walk per character are expensive, so one walk) onto the mannequin and
/// every labelled human rig with legs: the mannequin, the Godot robot, X Bot, Casual, the
/// UE-style mannequin and RobotExpressive, an IK-style rig (its feet are lone bones hanging
/// from the armature root beside the legs, its shins end in leaves: the retargeter carries
/// them at the shins' ends and the lock places them there). Measured on the CMU 131_01 walk:
/// RobotExpressive drift 0.0000 cm/frame (0.28 free), planted feet 0.75 cm of a 1.75 m body
/// off their standing height (1.33 cm of its own 1.54 m legs), largest kick 3.38 cm/frame²
/// against 2.57 free. Before its carried feet followed the root's calibration onto the floor
/// and the lock measured them where the retargeter carries them, 1.39 cm (its own) and 5.08.
#[test]
fn a_walk_keeps_its_feet_planted_on_every_human_character() {
    let Some((_, source, _)) = common::first_walk() else {
        return;
    };
    let mut targets = vec![mannequin_target()];
    for rig in common::human_rigs() {
        targets.push((rig.rel, rigcast_sources::load_rig(&rig.path).unwrap().0));
    }
    feet_stay_planted(&source, &targets);
}

/// The live path: the performer stage's causal detection and lock, frame by frame as the
/// tick runs them, on the mannequin and the first labelled human rig; drift is measured over
/// the (two-sided) plants. Expensive: the first walk onto the first rig only.
#[test]
fn a_walks_live_lock_keeps_planted_feet() {
    let Some((_, source, _)) = common::first_walk() else {
        return;
    };
    let mannequin = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let mut targets = vec![(
        "mannequin".to_string(),
        Clip::new(
            "mannequin",
            mannequin.clone(),
            vec![mannequin.rest_pose()],
            1.0 / 30.0,
        )
        .unwrap(),
    )];
    if let Some(rig) = common::human_rigs().into_iter().next() {
        targets.push((rig.rel, rigcast_sources::load_rig(&rig.path).unwrap().0));
    }
    let mut failures = Vec::new();
    for (name, target) in &targets {
        let (free, locked) = live_lock(&source, target);
        println!(
            "live, {name}: drift {:.4} cm/frame locked, {:.4} free (every foot joint: {:.4} \
             locked, {:.4} free); lowest below floor {:.2} cm locked; knee flips {}; largest \
             foot kick {:.2} cm/frame² locked, {:.2} free; planted feet off their standing \
             height {:.2} cm locked, {:.2} free (90th pct)",
            locked.contact_drift_cm_per_frame,
            free.contact_drift_cm_per_frame,
            locked.drift_cm_per_frame,
            free.drift_cm_per_frame,
            locked.deepest_below_floor_cm,
            locked.knee_flips,
            locked.largest_kick_cm,
            free.largest_kick_cm,
            locked.planted_off_standing_cm,
            free.planted_off_standing_cm,
        );
        let checks = [
            ("drift", locked.contact_drift_cm_per_frame <= 0.05),
            ("below the floor", locked.deepest_below_floor_cm <= 0.5),
            ("knee flips", locked.knee_flips == 0),
            // Locks blend in and out: no foot changes speed from one frame to the next much
            // more than in the animation itself.
            ("kick", locked.largest_kick_cm <= 1.5 * free.largest_kick_cm),
            // The live lock learns the fit to the standing posture as the performer walks
            // (the offline lock measures it on the whole clip first). Measured (cm of a
            // 1.75 m body): mannequin 0.18, Godot robot 0.27 (on every planted frame, before
            // its toeless feet rose with the heel: 0.21, 0.81, in their own cm 0.22, 0.58);
            // earlier, in their own cm, mannequin 0.48, X Bot 0.64, and without the fit 1.77
            // and 2.25.
            ("off standing", locked.planted_off_standing_cm <= 1.0),
        ];
        for (what, ok) in checks {
            if !ok {
                failures.push(format!("{name}: {what}: {locked:?} vs {free:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The CMU walk through the live path onto `target`, frame by frame as the tick runs it:
/// the figures without the lock and with it (drift over the two-sided plants).
fn live_lock(source: &Clip, target: &Clip) -> (Quality, Quality) {
    let skeleton = &target.skeleton;
    let plan = plan_mapping(source, target, None).unwrap();
    let opts = RetargetOptions {
        frame_time_secs: source.frame_time_secs as f32,
        source_up: Some(plan.source_up),
        ..RetargetOptions::default()
    };
    let mut mapping = Mapping::build(&[&source.skeleton], skeleton, &plan.table, &opts).unwrap();
    let mut lock = FootLock::new(
        &mapping,
        &plan.source_analysis,
        &plan.target_analysis,
        LockSettings::default(),
    )
    .unwrap();
    let dt = source.frame_time_secs as f32;
    let (mut free, mut locked) = (Vec::new(), Vec::new());
    let mut out = mapping.new_target_pose();
    for p in &source.poses {
        mapping.apply_one(p, &mut out).unwrap();
        free.push(out.clone());
        lock.apply_live(p, true, dt, &mut out);
        locked.push(out.clone());
    }
    let source_legs = find_legs(&source.skeleton, &plan.source_analysis);
    let plants = detect_clip(
        &source.skeleton,
        &source_legs,
        &source.poses,
        dt,
        plan.source_up,
        &PlantSettings::default(),
    );
    let legs: Vec<(Leg, usize)> = find_legs(skeleton, &plan.target_analysis)
        .into_iter()
        .filter_map(|l| Some((l, source_legs.iter().position(|s| s.key() == l.key())?)))
        .collect();
    let rest = world_transforms(skeleton, &skeleton.rest_pose());
    let as_clip = |poses: Vec<rigcast_retarget::Pose>| {
        Clip::new("out", skeleton.clone(), poses, source.frame_time_secs).unwrap()
    };
    let free_clip = as_clip(free);
    let axes = bend_axes(&free_clip, &legs);
    (
        measure(
            &free_clip,
            &legs,
            &plants,
            near_ground(&source_legs),
            &rest,
            &axes,
        ),
        measure(
            &as_clip(locked),
            &legs,
            &plants,
            near_ground(&source_legs),
            &rest,
            &axes,
        ),
    )
}

/// A target whose rest pose floats (a CMU-style skeleton: hips at the origin, feet 85 cm
/// below) locked from the first frame of real walks: the lock starts from where the animation
/// shows the feet, not from the floating rest. (It once measured the first landing from the
/// rest and pinned both feet about a metre up.) The animated feet stand on the floor there,
/// so a locked foot stays within a few centimetres of them.
#[test]
fn a_floating_rest_target_is_locked_where_its_feet_are_shown() {
    let Some(target) = common::shared_clip(common::CMU_WALK) else {
        return;
    };
    for rel in [
        "zoo/gltf/ue_style_mannequiny__godot_ragdoll.glb",
        "zoo/bvh/xsens__ammr_S02_Trial01.bvh",
    ] {
        let Some(p) = common::shared_data(rel) else {
            return;
        };
        let source = rigcast_sources::load_clip(&p).unwrap();
        let plan = plan_mapping(&source, &target, None).unwrap();
        let legs = find_legs(&target.skeleton, &plan.target_analysis);
        assert_eq!(legs.len(), 2, "{rel}: two target legs");
        let (free, locked) = (
            common::retarget(&source, &plan, &target, false),
            common::retarget(&source, &plan, &target, true),
        );
        let up = plan.source_up;
        let ankle_height = |clip: &Clip, i: usize, leg: &Leg| {
            world_transforms(&clip.skeleton, &clip.poses[i])[leg.foot.index()]
                .translation
                .dot(up)
        };
        let mut first_cm: f32 = 0.0;
        let mut worst_cm: f32 = 0.0;
        for i in 0..free.num_frames() {
            for leg in &legs {
                let d = 100.0 * (ankle_height(&locked, i, leg) - ankle_height(&free, i, leg)).abs();
                worst_cm = worst_cm.max(d);
                if i == 0 {
                    first_cm = first_cm.max(d);
                }
            }
        }
        println!("{rel} → CMU skeleton: locked ankles off the animated ones by {first_cm:.2} cm on the first frame, {worst_cm:.2} cm at most");
        assert!(first_cm <= 3.0, "{rel}: first frame {first_cm} cm");
        assert!(worst_cm <= 10.0, "{rel}: {worst_cm} cm");
    }
}

/// Live, a character whose posture does not stand on its floor is pinned at the heights its
/// animation stands at, as offline (where `fit_to_standing` reads them off the animation):
/// MakeHuman's rest stands along its own up, not this world's, so the retarget places no
/// floor under it. Pinned at its rest's heights, the pymo Meredith walk put MakeHuman's pins
/// up to 9 cm under the animation's standing ankles and the body came down onto them (the
/// planted ankles 3.1 cm off the animation's on the median frame; 1.5 cm learnt).
#[test]
fn a_live_character_whose_posture_does_not_stand_is_pinned_at_its_animations_heights() {
    let (Some(s), Some(t)) = (
        common::shared_data("zoo/bvh/sparse_spine_head__pymo_meredith.bvh"),
        common::shared_data("zoo/bvh/makehuman__walk1.bvh"),
    ) else {
        return;
    };
    let (source, target) = (
        rigcast_sources::load_clip(&s).unwrap(),
        rigcast_sources::load_clip(&t).unwrap(),
    );
    let plan = plan_mapping(&source, &target, None).unwrap();
    let opts = plan.retarget_options(&source, rigcast_retarget::RootMotion::Scaled);
    let skeleton = &target.skeleton;
    let mut mapping = Mapping::build(&[&source.skeleton], skeleton, &plan.table, &opts).unwrap();
    if let Some(floor) = mapping.measure_source_floor(&source.poses) {
        mapping.set_source_floor_y(floor);
    }
    let (sa, ta) = (&plan.source_analysis, &plan.target_analysis);
    let mut lock = FootLock::new(&mapping, sa, ta, LockSettings::default()).unwrap();
    let dt = source.frame_time_secs as f32;
    let source_legs = find_legs(&source.skeleton, sa);
    let plants = detect_clip(
        &source.skeleton,
        &source_legs,
        &source.poses,
        dt,
        sa.up,
        &PlantSettings::default(),
    );
    let legs: Vec<(Leg, usize)> = find_legs(skeleton, ta)
        .into_iter()
        .filter_map(|l| Some((l, source_legs.iter().position(|s| s.key() == l.key())?)))
        .collect();
    assert_eq!(legs.len(), 2);
    let up = plan.source_up;
    let ankle = |pose: &rigcast_retarget::Pose, leg: &Leg| {
        world_transforms(skeleton, pose)[leg.foot.index()]
            .translation
            .dot(up)
    };
    // How far each planted ankle stands from the animation's, past the first second (its
    // first stance is what it learns from).
    let mut off: Vec<f32> = Vec::new();
    let mut out = mapping.new_target_pose();
    for (i, p) in source.poses.iter().enumerate() {
        mapping.apply_one(p, &mut out).unwrap();
        let free = out.clone();
        lock.apply_live(p, true, dt, &mut out);
        if (i as f32) * dt < 1.0 {
            continue;
        }
        for (leg, s) in &legs {
            if plants.is_planted(i, *s) {
                off.push(100.0 * (ankle(&out, leg) - ankle(&free, leg)).abs());
            }
        }
    }
    off.sort_by(f32::total_cmp);
    let median = off[off.len() / 2];
    println!(
        "planted ankles off the animation's: median {median:.2} cm over {} frames",
        off.len()
    );
    assert!(median < 2.0, "{median} cm");
}
