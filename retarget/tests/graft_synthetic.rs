//! Grafting on generated humanoids, where the answers are known by construction:
//! - the splice keeps the locomotion's legs exactly, stands the chest as the graft's torso
//!   turned to the locomotion's heading, and keeps the graft's arm relative to the chest;
//! - a looping stride is continuous across its seam and carries the walker on by one stride's
//!   travel per loop;
//! - neither allocates per frame (counting allocator).

mod alloc_count;
mod retarget_fixtures;

use glam::{Quat, Vec3};
use retarget_fixtures::{positions, Humanoid};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{find_legs, PlantTrack};
use rigcast_retarget::graft::{BodySplit, GaitLoop, Half, Splice};
use rigcast_retarget::{world_transforms, Clip, Pose, Skeleton};

fn setup() -> (Skeleton, BodySplit) {
    let skel = Humanoid {
        spine_bones: 3,
        ..Humanoid::default()
    }
    .build();
    let a = analyze(&SkeletonView::rest(&skel));
    let split = BodySplit::new(&skel, &a, 2).expect("a humanoid splits");
    (skel, split)
}

fn bone(skel: &Skeleton, name: &str) -> usize {
    skel.bone(name).expect(name).index()
}

#[test]
fn the_cut_is_at_the_pelvis_and_blends_over_the_spine() {
    let (skel, split) = setup();
    assert_eq!(skel.name(split.waist), "hips");
    let names: Vec<&str> = split.spine.iter().map(|&b| skel.name(b)).collect();
    assert_eq!(names, ["spine", "chest", "upper_chest"]);
    let blend: Vec<(&str, f32)> = split
        .blend
        .iter()
        .map(|&(b, w)| (skel.name(b), w))
        .collect();
    assert_eq!(blend, [("spine", 0.5), ("chest", 1.0)]);
    for (name, half) in [
        ("hips", Half::Lower),
        ("l_thigh", Half::Lower),
        ("r_toe", Half::Lower),
        ("spine", Half::Upper),
        ("l_hand", Half::Upper),
        ("head", Half::Upper),
    ] {
        assert_eq!(split.half(skel.bone(name).expect(name)), half, "{name}");
    }
}

#[test]
fn the_splice_keeps_the_legs_and_turns_the_graft_torso_to_the_walk_heading() {
    let (skel, split) = setup();
    let rest = skel.rest_pose();
    // Locomotion: turned 0.3 rad, a thigh and a shin bent, the spine leaning.
    let mut lower = rest.clone();
    lower.rotations[0] = Quat::from_rotation_y(0.3);
    lower.translations[0] += Vec3::new(0.5, -0.02, 1.0);
    lower.rotations[bone(&skel, "l_thigh")] *= Quat::from_rotation_x(-0.5);
    lower.rotations[bone(&skel, "l_shin")] *= Quat::from_rotation_x(0.7);
    lower.rotations[bone(&skel, "spine")] *= Quat::from_rotation_x(0.2);
    // Graft: facing 1.9 rad elsewhere, its torso twisted 0.25 rad and leaning sideways,
    // its left arm raised.
    let mut upper = rest.clone();
    upper.rotations[0] = Quat::from_rotation_y(1.9);
    upper.translations[0] += Vec3::new(-3.0, 0.0, 2.0);
    let torso = Quat::from_rotation_y(0.25) * Quat::from_rotation_z(0.15);
    upper.rotations[bone(&skel, "spine")] *= torso;
    upper.rotations[bone(&skel, "l_upper_arm")] *= Quat::from_rotation_z(0.9);
    upper.rotations[bone(&skel, "l_forearm")] *= Quat::from_rotation_y(0.6);
    let mut out = rest.clone();
    let mut splice = Splice::new(&skel, split.clone());
    assert!(splice.apply(&lower, &upper, &mut out));
    let (wo, wl, wu) = (
        world_transforms(&skel, &out),
        world_transforms(&skel, &lower),
        world_transforms(&skel, &upper),
    );
    for b in skel.bone_ids() {
        if split.half(b) == Half::Lower {
            assert!((wo[b.index()].translation - wl[b.index()].translation).length() < 1e-5);
        }
    }
    // The chest (last blended bone) is the graft's, turned by the heading difference.
    let turn = Quat::from_rotation_y(0.3 - 1.9);
    let chest = bone(&skel, "chest");
    let want = turn * wu[chest].rotation;
    assert!(rigcast_retarget::approx::quat_angle(wo[chest].rotation, want) < 1e-4);
    // The arm relative to the chest: the graft's.
    let hand = bone(&skel, "l_hand");
    let rel = |w: &[rigcast_retarget::WorldTransform]| {
        w[chest].rotation.inverse() * (w[hand].translation - w[chest].translation)
    };
    assert!((rel(&wo) - rel(&wu)).length() < 1e-5);
    // The blended spine bone lies between the walk's and the graft's (turned) world rotations.
    let spine = bone(&skel, "spine");
    let (a, b) = (wl[spine].rotation, turn * wu[spine].rotation);
    let (da, db) = (
        rigcast_retarget::approx::quat_angle(wo[spine].rotation, a),
        rigcast_retarget::approx::quat_angle(wo[spine].rotation, b),
    );
    assert!((da - db).abs() < 1e-3 && da > 0.01, "{da} {db}");
    // A pose of another skeleton is refused without a panic.
    assert!(!splice.apply(
        &Pose::from_rest(&Humanoid::default().build()),
        &upper,
        &mut out
    ));
}

/// A walk cycle with period `period` frames: hips travelling forward, a thigh swinging, and
/// landings alternating every half period.
fn walk(skel: &Skeleton, frames: usize, period: usize) -> (Clip, PlantTrack) {
    let rest = skel.rest_pose();
    let thigh = bone(skel, "l_thigh");
    let poses: Vec<Pose> = (0..frames)
        .map(|f| {
            let phase = std::f32::consts::TAU * f as f32 / period as f32;
            let mut p = rest.clone();
            p.translations[0] += Vec3::new(0.0, 0.02 * (2.0 * phase).sin(), 0.01 * f as f32);
            p.rotations[thigh] *= Quat::from_rotation_x(0.4 * phase.sin());
            p
        })
        .collect();
    let a = analyze(&SkeletonView::rest(skel));
    let legs = find_legs(skel, &a);
    assert_eq!(legs.len(), 2);
    // Leg 0 lands at 5 + k·period, leg 1 half a period later; each stands 30 % of a period.
    let flags = (0..frames)
        .flat_map(|f| {
            (0..2).map(move |l| {
                let start = 5 + l * period / 2;
                f >= start && (f - start) % period < period * 3 / 10
            })
        })
        .collect();
    let clip = Clip::new("walk", skel.clone().into(), poses, 1.0 / 60.0).expect("clip");
    (clip, PlantTrack::from_flags(legs, flags))
}

#[test]
fn a_looping_stride_is_continuous_and_walks_on() {
    let (skel, _) = setup();
    let (clip, plants) = walk(&skel, 200, 60);
    let mut gait = GaitLoop::new(&clip, &plants, Vec3::Y).expect("a stride");
    assert!(
        (gait.stride_secs() - 1.0).abs() < 1e-9,
        "{}",
        gait.stride_secs()
    );
    let mut pose = skel.rest_pose();
    let dt = 1.0 / 90.0;
    gait.advance(0.0, &mut pose);
    let start = pose.translations[0];
    let mut last = positions(&skel, &pose);
    let mut largest_step: f32 = 0.0;
    let mut planted_frames = 0;
    for _ in 0..(3.0 / dt) as usize {
        planted_frames += gait.advance(dt, &mut pose).iter().filter(|&&p| p).count();
        let now = positions(&skel, &pose);
        for (a, b) in now.iter().zip(&last) {
            largest_step = largest_step.max((*a - *b).length());
        }
        last = now;
    }
    // The swinging toes move at up to ~3 m/s (33 mm per 90 Hz step); a jump at the seam (the
    // stride's 0.6 m travel undone) would show as ~0.6 m.
    assert!(largest_step < 0.05, "largest step {largest_step}");
    let travelled = pose.translations[0] - start;
    assert!((travelled.z - 1.8).abs() < 0.02, "{travelled}");
    // Each foot stands 30 % of the time.
    let share = planted_frames as f32 / (2.0 * 3.0 / dt as f32);
    assert!((share - 0.3).abs() < 0.05, "{share}");
}

#[test]
fn a_clip_without_a_full_stride_is_an_error() {
    let (skel, _) = setup();
    let (clip, plants) = walk(&skel, 40, 60);
    assert!(GaitLoop::new(&clip, &plants, Vec3::Y).is_err());
}

#[test]
fn splicing_and_looping_allocate_nothing() {
    let (skel, split) = setup();
    let (clip, plants) = walk(&skel, 200, 60);
    let mut gait = GaitLoop::new(&clip, &plants, Vec3::Y).expect("a stride");
    let mut splice = Splice::new(&skel, split);
    let (mut lower, mut out) = (skel.rest_pose(), skel.rest_pose());
    let upper = clip.poses[17].clone();
    gait.advance(0.01, &mut lower);
    splice.apply(&lower, &upper, &mut out);
    let before = alloc_count::allocations();
    for _ in 0..500 {
        gait.advance(1.0 / 60.0, &mut lower);
        splice.apply(&lower, &upper, &mut out);
    }
    assert_eq!(alloc_count::allocations() - before, 0);
}
