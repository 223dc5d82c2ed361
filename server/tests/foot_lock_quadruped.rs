//! Foot locking on a quadruped target (issue 13): the first labelled walk (found by its motion)
//! retargeted offline onto every labelled quadruped rig with four labelled legs (today
//! Quaternius' Horse and Wolf; front legs driven by the walker's arms). Measured on the output: the rig's four feet are found (two hind, two front),
//! the feet the source's plants drive (the hind ones) hold still while planted, no heel or
//! ball joint of any of the four feet goes below its standing height by more than 0.5 cm more
//! than the unlocked retarget already does, and no knee or elbow flips its bend (the sign of
//! its bend axis in the upper bone's frame, against the unlocked output's). Skips with a
//! printed reason when the shared data is absent.
//!
//! On the Horse and the Wolf: four feet found, no flips; the unlocked retarget keeps the
//! Horse's hind foot joint (the hock, 1.3 m up when it stands) within 5 cm of its standing
//! height (median while the walker's feet are down), and the locked one at it (the lock
//! measures clearances from the ground under raised contacts); planted hind feet hold
//! (0.000 cm/frame on the Horse, ≤ 0.01 on the Wolf). The front legs, driven by the walker's arms, and the whole body keep the rig's own
//! standing posture and follow the walker's motion from its standing posture (its clip's mean
//! posture), the trunk by its heading alone: see the last test for their figures.
#![allow(clippy::unwrap_used)]

mod common;

use glam::Vec3;
use rigcast_retarget::footplant::{detect_clip, find_legs, Leg, LegKind, PlantSettings};
use rigcast_retarget::{world_transforms, Clip, RetargetOptions, WorldTransform};
use rigcast_server::offline::{plan_mapping, MappingPlan};

/// The first labelled walk (found by its motion; retargeting a whole walk is expensive, so one)
/// and every labelled quadruped rig (not a BVH clip) whose four legs are labelled (name, rig);
/// `None` (printed) without them.
fn walk_and_quadrupeds() -> Option<(Clip, Vec<(String, Clip)>)> {
    let (_, source, _) = common::first_walk()?;
    let rigs = common::labelled_where("quadruped rig with four labelled legs", |l| {
        l.four_legged() && !l.is_bvh()
    });
    let targets: Vec<(String, Clip)> = rigs
        .into_iter()
        .map(|l| (l.rel, rigcast_sources::load_rig(&l.path).unwrap().0))
        .collect();
    (!targets.is_empty()).then_some((source, targets))
}

/// The source's legs and their plants over the whole clip (two-sided).
fn source_plants(
    source: &Clip,
    plan: &MappingPlan,
) -> (Vec<Leg>, rigcast_retarget::footplant::PlantTrack) {
    let legs = find_legs(&source.skeleton, &plan.source_analysis);
    let plants = plants_of(source, &legs, plan.source_up);
    (legs, plants)
}

/// Two-sided plants of `clip` on `legs`, heights along `up`, default thresholds.
fn plants_of(clip: &Clip, legs: &[Leg], up: Vec3) -> rigcast_retarget::footplant::PlantTrack {
    detect_clip(
        &clip.skeleton,
        legs,
        &clip.poses,
        clip.frame_time_secs as f32,
        up,
        &PlantSettings::default(),
    )
}

fn worlds(c: &Clip) -> Vec<Vec<WorldTransform>> {
    c.poses
        .iter()
        .map(|p| world_transforms(&c.skeleton, p))
        .collect()
}

/// Deepest a heel or ball joint of `leg` goes below its standing (rest) height, metres.
fn deepest(w: &[Vec<WorldTransform>], rest: &[WorldTransform], leg: &Leg) -> f32 {
    let joints: Vec<_> = [Some(leg.foot), leg.toes].into_iter().flatten().collect();
    w.iter()
        .flat_map(|f| {
            joints
                .iter()
                .map(move |j| rest[j.index()].translation.y - f[j.index()].translation.y)
        })
        .fold(f32::NEG_INFINITY, f32::max)
}

/// The bend axis of the middle joint in the upper bone's frame, per frame (zero when straight).
fn bend_axes(w: &[Vec<WorldTransform>], leg: &Leg) -> Vec<Vec3> {
    w.iter()
        .map(|f| {
            let p = |b: rigcast_retarget::BoneId| f[b.index()].translation;
            let (a, b, c) = (p(leg.upper), p(leg.lower), p(leg.foot));
            if (b - a).angle_between(c - b).to_degrees() < 10.0 {
                return Vec3::ZERO;
            }
            f[leg.upper.index()].rotation.inverse() * (b - a).cross(c - b).normalize_or_zero()
        })
        .collect()
}

/// One target foot's figures: locked and free depth below its standing height (m), knee
/// flips, and mean horizontal drift (cm/frame) over `planted` frames of its source foot's
/// plants (`None` for a foot no source plant drives).
#[derive(Debug)]
struct FootFigures {
    rig: String,
    name: String,
    locked_depth: f32,
    free_depth: f32,
    flips: usize,
    drift: Option<(f32, usize)>,
}

/// The CMU walk locked and free on every quadruped, per foot (printed); `None` (printed)
/// without the shared data.
fn measure_quadrupeds() -> Option<Vec<FootFigures>> {
    let (source, targets) = walk_and_quadrupeds()?;
    let mut figures = Vec::new();
    for (rel, target) in &targets {
        let plan = plan_mapping(&source, target, None).unwrap();
        let legs = find_legs(&target.skeleton, &plan.target_analysis);
        let kinds = |k: LegKind| legs.iter().filter(|l| l.kind == k).count();
        println!(
            "{rel}: {} hind and {} front feet",
            kinds(LegKind::Hind),
            kinds(LegKind::Front)
        );
        assert_eq!(
            (kinds(LegKind::Hind), kinds(LegKind::Front)),
            (2, 2),
            "{rel}"
        );
        let mapping = rigcast_retarget::Mapping::build(
            &[&source.skeleton],
            &target.skeleton,
            &plan.table,
            &RetargetOptions {
                source_reference: vec![plan.source_reference.clone()],
                target_reference: plan.target_reference.clone(),
                source_up: Some(plan.source_up),
                ..RetargetOptions::default()
            },
        )
        .unwrap();
        let rest_w = world_transforms(&target.skeleton, &target.skeleton.rest_pose());
        let lowest_rest = legs
            .iter()
            .map(|l| rest_w[l.foot.index()].translation.y)
            .fold(f32::INFINITY, f32::min);
        println!(
            "  the mapping's floor {:?}, the rest's lowest ankle {lowest_rest:.3}",
            mapping.target_floor().map(|f| f.1)
        );
        let (free, locked) = (
            common::retarget(&source, &plan, target, false),
            common::retarget(&source, &plan, target, true),
        );
        let (wf, wl) = (worlds(&free), worlds(&locked));
        let rest = world_transforms(&target.skeleton, &target.skeleton.rest_pose());
        let (source_legs, plants) = source_plants(&source, &plan);
        for leg in &legs {
            let name = target.skeleton.name(leg.foot);
            let (df, dl) = (deepest(&wf, &rest, leg), deepest(&wl, &rest, leg));
            let (af, al) = (bend_axes(&wf, leg), bend_axes(&wl, leg));
            let reference = af.iter().fold(Vec3::ZERO, |s, a| s + *a);
            let flips = al.iter().filter(|a| a.dot(reference) < 0.0).count();
            // Drift of a hind foot while its source foot is planted.
            let src = source_legs.iter().position(|s| s.key() == leg.key());
            let (mut drift, mut n) = (0.0f32, 0);
            if let Some(s) = src {
                for f in 1..locked.num_frames() {
                    if plants.is_planted(f, s) && plants.is_planted(f - 1, s) {
                        let m = wl[f][leg.foot.index()].translation
                            - wl[f - 1][leg.foot.index()].translation;
                        drift += Vec3::new(m.x, 0.0, m.z).length() * 100.0;
                        n += 1;
                    }
                }
            }
            let drift = drift / n.max(1) as f32;
            println!(
                "  {name} ({:?}): below floor {:.2} cm locked, {:.2} free; flips {flips}; drift while planted {drift:.4} cm/frame ({n} frames)",
                leg.kind,
                dl * 100.0,
                df * 100.0
            );
            figures.push(FootFigures {
                rig: rel.clone(),
                name: name.to_string(),
                locked_depth: dl,
                free_depth: df,
                flips,
                drift: src.map(|_| (drift, n)),
            });
        }
    }
    Some(figures)
}

/// No heel or ball joint of the four feet goes lower under the lock than without it (beyond
/// 0.5 cm), and no knee or elbow flips.
#[test]
fn cmu_walk_on_quadrupeds_keeps_four_feet_above_the_floor_without_flips() {
    let Some(figures) = measure_quadrupeds() else {
        return;
    };
    for f in &figures {
        assert!(
            f.locked_depth <= f.free_depth.max(0.0) + 0.005,
            "{} {}: {} below vs {} free",
            f.rig,
            f.name,
            f.locked_depth,
            f.free_depth
        );
        assert_eq!(f.flips, 0, "{} {}", f.rig, f.name);
    }
}

/// The hind feet the walker's plants drive hold still while planted (≤ 0.05 cm/frame).
#[test]
fn cmu_walk_on_quadrupeds_holds_planted_hind_feet() {
    let Some(figures) = measure_quadrupeds() else {
        return;
    };
    for f in &figures {
        if let Some((drift, n)) = f.drift {
            assert!(
                n > 100 && drift <= 0.05,
                "{} {}: drift {drift} over {n}",
                f.rig,
                f.name
            );
        }
    }
}

/// A hoofed or digitigrade hind leg whose mapped joints end well above the ground (the Horse's
/// and Wolf's hocks) holds the body up at its own standing height while the walker's feet are
/// down, instead of being put on the floor with the body sunk by the leg's unmapped part: over
/// the frames where both source feet are planted, the median hips height is within 10 % of
/// the rig's standing hips height (its rest, or the frame of its own animation the mapping
/// uses when the rest is no posture), and each hind foot joint stays at least half its
/// standing height above the floor.
#[test]
fn raised_hind_feet_keep_the_body_at_its_standing_height() {
    let Some((source, targets)) = walk_and_quadrupeds() else {
        return;
    };
    for (rel, target) in &targets {
        let plan = plan_mapping(&source, target, None).unwrap();
        let legs = find_legs(&target.skeleton, &plan.target_analysis);
        let free = worlds(&common::retarget(&source, &plan, target, false));
        let standing_pose = plan
            .target_reference
            .clone()
            .unwrap_or_else(|| target.skeleton.rest_pose());
        let standing = world_transforms(&target.skeleton, &standing_pose);
        let hips = plan
            .target_analysis
            .find(
                rigcast_retarget::analysis::Role::Hips,
                rigcast_retarget::analysis::Side::Center,
            )
            .unwrap();
        let (source_legs, plants) = source_plants(&source, &plan);
        let both_down: Vec<usize> = (0..free.len())
            .filter(|&f| (0..source_legs.len()).all(|l| plants.is_planted(f, l)))
            .collect();
        assert!(
            both_down.len() > 20,
            "{rel}: {} frames with both feet down",
            both_down.len()
        );
        let median = |bone: rigcast_retarget::BoneId| {
            let mut h: Vec<f32> = both_down
                .iter()
                .map(|&f| free[f][bone.index()].translation.y)
                .collect();
            h.sort_by(f32::total_cmp);
            h[h.len() / 2]
        };
        let (hips_at, hips_stands) = (median(hips), standing[hips.index()].translation.y);
        println!(
            "{rel}: hips at {hips_at:.3} m (median, both walker feet down), stand at {hips_stands:.3} m"
        );
        assert!(
            (hips_at - hips_stands).abs() <= 0.1 * hips_stands,
            "{rel}: hips at {hips_at} m, stand at {hips_stands} m"
        );
        for leg in legs.iter().filter(|l| l.kind == LegKind::Hind) {
            let (at, stands) = (median(leg.foot), standing[leg.foot.index()].translation.y);
            let name = target.skeleton.name(leg.foot);
            println!("  {name}: at {at:.3} m, stands at {stands:.3} m");
            assert!(
                at >= 0.5 * stands,
                "{rel} {name}: at {at} m, stands at {stands} m"
            );
        }
    }
}

/// Plant detection on a quadruped's motion, through the rig's roles: on the walk locked onto
/// the Horse and the Wolf, the detector run on the output finds the hind feet planted where
/// the walker's plants held them (≥ 90 % of frames agree; judged with the two-sided
/// detector, which looks at the output alone).
#[test]
fn plants_are_found_on_a_quadrupeds_hind_feet() {
    let Some((source, targets)) = walk_and_quadrupeds() else {
        return;
    };
    let mut failures: Vec<String> = Vec::new();
    for (rel, target) in &targets {
        let plan = plan_mapping(&source, target, None).unwrap();
        let locked = common::retarget(&source, &plan, target, true);
        let (source_legs, source_track) = source_plants(&source, &plan);
        let legs = find_legs(&target.skeleton, &plan.target_analysis);
        let found = plants_of(&locked, &legs, plan.source_up);
        let mut compared = 0;
        let mut worst = 1.0f64;
        for (i, leg) in legs.iter().enumerate() {
            let Some(s) = source_legs.iter().position(|l| l.key() == leg.key()) else {
                continue;
            };
            let n = found.num_frames();
            let agree = (0..n)
                .filter(|&f| found.is_planted(f, i) == source_track.is_planted(f, s))
                .count() as f64
                / n as f64;
            let planted = (0..n).filter(|&f| found.is_planted(f, i)).count();
            println!(
                "{rel} {}: {planted} of {n} frames planted, {:.1} % agree with the walker's",
                target.skeleton.name(leg.foot),
                100.0 * agree
            );
            compared += 1;
            worst = worst.min(agree);
        }
        assert_eq!(
            compared, 2,
            "{rel}: the walker's two feet drive the hind feet"
        );
        if worst < 0.9 {
            failures.push(format!("{rel}: {:.1} % agree", 100.0 * worst));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// The `p`th percentile (0..=100) of `v` (sorted in place); NaN when empty.
fn percentile(v: &mut [f32], p: usize) -> f32 {
    if v.is_empty() {
        return f32::NAN;
    }
    v.sort_by(f32::total_cmp);
    v[(v.len() - 1) * p / 100]
}

/// A quadruped's body on the walk, unlocked: how far its trunk pitches from its standing
/// pitch, how far its front legs' lower joints get from their standing heights, whether its
/// knees and elbows bend against their standing bend, and how far the front feet swing.
#[derive(Debug)]
struct BodyFigures {
    rig: String,
    /// Hips → chest pitch minus the standing one, degrees: 90th percentile and worst.
    pitch_p90: f32,
    pitch_max: f32,
    /// Front knee (forearm top) and foot joints' |height − standing height|, metres, over
    /// both front legs: 90th percentile and worst.
    front_p90: f32,
    front_max: f32,
    /// The same, median.
    front_p50: f32,
    /// Shortest front leg (shoulder to foot joint along the bones at the analysed posture), m.
    front_leg: f32,
    /// The rig's standing hips height, m (the scale of the bounds).
    hips_stands: f32,
    /// Frames whose bend axis (any of the four legs) opposes the standing bend.
    flips: usize,
    /// Smallest fore-aft swing of a front foot relative to the hips (5th–95th percentile
    /// range, metres).
    front_swing: f32,
}

fn measure_bodies() -> Option<Vec<BodyFigures>> {
    use rigcast_retarget::analysis::{Role, Side};
    let (source, targets) = walk_and_quadrupeds()?;
    let mut out = Vec::new();
    for (rel, target) in &targets {
        let plan = plan_mapping(&source, target, None).unwrap();
        let ta = &plan.target_analysis;
        let legs = find_legs(&target.skeleton, ta);
        let free = worlds(&common::retarget(&source, &plan, target, false));
        let standing_pose = plan
            .target_reference
            .clone()
            .unwrap_or_else(|| target.skeleton.rest_pose());
        let standing = world_transforms(&target.skeleton, &standing_pose);
        let hips = ta.find(Role::Hips, Side::Center).unwrap();
        let chest = ta.find(Role::Chest, Side::Center).unwrap();
        let pitch = |w: &[WorldTransform]| {
            let d =
                (w[chest.index()].translation - w[hips.index()].translation).normalize_or_zero();
            d.y.clamp(-1.0, 1.0).asin().to_degrees()
        };
        let stand_pitch = pitch(&standing);
        let mut pitches: Vec<f32> = free
            .iter()
            .map(|f| (pitch(f) - stand_pitch).abs())
            .collect();
        let front: Vec<&Leg> = legs.iter().filter(|l| l.kind == LegKind::Front).collect();
        let mut heights = Vec::new();
        for f in &free {
            for l in &front {
                for j in [l.lower, l.foot] {
                    let h = f[j.index()].translation.y - standing[j.index()].translation.y;
                    heights.push(h.abs());
                }
            }
        }
        let bend = |f: &[WorldTransform], leg: &Leg| {
            let p = |b: rigcast_retarget::BoneId| f[b.index()].translation;
            let (a, b, c) = (p(leg.upper), p(leg.lower), p(leg.foot));
            if (b - a).angle_between(c - b).to_degrees() < 10.0 {
                return Vec3::ZERO;
            }
            f[leg.upper.index()].rotation.inverse() * (b - a).cross(c - b).normalize_or_zero()
        };
        let flips = free
            .iter()
            .filter(|f| {
                legs.iter()
                    .any(|l| bend(f, l).dot(bend(&standing, l)) < 0.0)
            })
            .count();
        let front_swing = front
            .iter()
            .map(|l| {
                let mut along: Vec<f32> = free
                    .iter()
                    .map(|f| {
                        let fwd = f[chest.index()].translation - f[hips.index()].translation;
                        let fwd = Vec3::new(fwd.x, 0.0, fwd.z).normalize_or_zero();
                        (f[l.foot.index()].translation - f[hips.index()].translation).dot(fwd)
                    })
                    .collect();
                let lo = percentile(&mut along, 5);
                percentile(&mut along, 95) - lo
            })
            .fold(f32::INFINITY, f32::min);
        let figures = BodyFigures {
            rig: rel.clone(),
            pitch_p90: percentile(&mut pitches, 90),
            pitch_max: percentile(&mut pitches, 100),
            front_p50: percentile(&mut heights, 50),
            front_p90: percentile(&mut heights, 90),
            front_max: percentile(&mut heights, 100),
            front_leg: front.iter().map(|l| l.length).fold(f32::INFINITY, f32::min),
            hips_stands: standing[hips.index()].translation.y,
            flips,
            front_swing,
        };
        println!(
            "{rel}: trunk pitch off standing {:.1}° (p90), {:.1}° worst; front knee/foot off standing height {:.1} cm (median), {:.1} cm (p90), {:.1} cm worst, front leg {:.1} cm; {} frames with a bend against the standing one; front feet swing {:.1} cm",
            figures.pitch_p90,
            figures.pitch_max,
            figures.front_p50 * 100.0,
            figures.front_p90 * 100.0,
            figures.front_max * 100.0,
            figures.front_leg * 100.0,
            figures.flips,
            figures.front_swing * 100.0
        );
        out.push(figures);
    }
    Some(out)
}

/// The walker's body on a quadruped's (issue 13), unlocked: the trunk keeps its standing
/// pitch (p90 within 5°) while it turns with the walker; the front legs' elbow and foot
/// joints stay near their standing heights (median within 10 % of the standing hips height,
/// 90th percentile within 25 %: the walker's gestures lift them, its crouch lowers the body);
/// no knee or elbow of the four legs bends against its standing bend; the front feet swing
/// fore and aft (at least 25 cm). Before: the trunk pitched 92–99° (reared like the walker),
/// the front joints hung 2.3–4.2 m (p90) off their standing heights. Now: pitch 0.0°, front
/// joints 12 cm (median) and 60 cm / 28 cm (p90, Horse / Wolf, standing hips 3.1 m / 2.0 m),
/// no bend flips, swings of 143 cm / 50 cm.
#[test]
fn cmu_walk_on_quadrupeds_keeps_the_body_level_and_the_front_feet_down() {
    let Some(figures) = measure_bodies() else {
        return;
    };
    for f in &figures {
        assert!(
            f.pitch_p90 <= 5.0,
            "{}: trunk pitch {}°",
            f.rig,
            f.pitch_p90
        );
        assert!(
            f.front_p50 <= 0.1 * f.hips_stands && f.front_p90 <= 0.25 * f.hips_stands,
            "{}: front joints {} m (median), {} m (p90) off, hips stand at {} m",
            f.rig,
            f.front_p50,
            f.front_p90,
            f.hips_stands
        );
        assert_eq!(f.flips, 0, "{}: bends against the standing one", f.rig);
        assert!(
            f.front_swing >= 0.25,
            "{}: front feet swing {} m",
            f.rig,
            f.front_swing
        );
    }
}
