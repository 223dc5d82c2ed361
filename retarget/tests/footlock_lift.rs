//! A planted foot's clearance: the plants of a clip say how high each foot stands above its
//! ground, and offline the lock holds a pinned target foot as far above its standing height as
//! that, scaled, up to a limit (a foot farther up is landing, or on ground of its own); a
//! source whose feet hang from its root has its plants watched all the same.

mod retarget_fixtures;

use retarget_fixtures::{locked_pair, Humanoid};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{detect_clip, find_contact_legs, find_legs, PlantSettings};
use rigcast_retarget::{world_transforms, Pose, Skeleton, Transform};

/// Standing still at 60 Hz for `n` frames, the whole body `rise(f)` metres up on frame `f`.
fn standing(source: &Skeleton, n: usize, rise: impl Fn(usize) -> f32) -> Vec<Pose> {
    let rest = source.rest_pose();
    (0..n)
        .map(|f| {
            let mut p = rest.clone();
            p.translations[0].y += rise(f);
            p
        })
        .collect()
}

/// 0 until frame 60, then up by `by` metres over 20 frames (slowly: the feet stay planted).
fn settle_up(by: f32) -> impl Fn(usize) -> f32 {
    move |f| by * ((f as f32 - 60.0) / 20.0).clamp(0.0, 1.0)
}

#[test]
fn plants_say_how_high_a_foot_stands_above_its_ground() {
    let (source, _, _, lock) = locked_pair();
    let legs = lock.source_legs().to_vec();
    let plants = |poses: &[Pose]| {
        detect_clip(
            &source,
            &legs,
            poses,
            1.0 / 60.0,
            glam::Vec3::Y,
            &PlantSettings::default(),
        )
    };
    // Standing, then 4 mm up: one plant throughout, the feet 4 mm above their ground.
    let up = plants(&standing(&source, 120, settle_up(0.004)));
    for (leg, _) in legs.iter().enumerate() {
        let plants = up.intervals(leg);
        assert!(plants.len() == 1 && plants[0] == (0..120), "{plants:?}");
        assert!(up.lifts(30)[leg].abs() < 1e-4, "{}", up.lifts(30)[leg]);
        assert!(
            (up.lifts(110)[leg] - 0.004).abs() < 2e-4,
            "{}",
            up.lifts(110)[leg]
        );
    }
}

#[test]
fn a_pinned_foot_follows_the_source_clearance_up_to_a_limit() {
    let (source, target, mapping, lock) = locked_pair();
    let foot = target.bone("l_foot").expect("foot");
    let rest = world_transforms(&target, &target.rest_pose());
    let standing_height = rest[foot.index()].translation.y;
    let scale = mapping.root_scale().expect("a root");
    let target_leg = lock.target_legs().next().expect("a leg").length;
    let legs = lock.source_legs().to_vec();
    // Where the left ankle is on the last frame, the clip's plants given with their heights
    // (`track`) or as flags only.
    let last_ankle = |by: f32, track: bool| {
        let poses = standing(&source, 120, settle_up(by));
        let plants = detect_clip(
            &source,
            &legs,
            &poses,
            1.0 / 60.0,
            glam::Vec3::Y,
            &PlantSettings::default(),
        );
        let (mut mapping, mut lock) = (mapping.clone(), lock.clone());
        let mut out = mapping.new_target_pose();
        for (f, p) in poses.iter().enumerate() {
            mapping.apply_one(p, &mut out).expect("apply");
            if track {
                lock.apply_track(&plants, f, 1.0 / 60.0, &mut out);
            } else {
                lock.apply_planted(plants.frame(f), 1.0 / 60.0, &mut out);
            }
        }
        world_transforms(&target, &out)[foot.index()].translation.y - standing_height
    };
    // 4 mm up on the source: the target's foot stands that much up, scaled.
    let followed = last_ankle(0.004, true);
    assert!(
        (followed - 0.004 * scale).abs() < 5e-4,
        "the ankle is {followed} m up, the source's clearance scaled {}",
        0.004 * scale
    );
    // Given flags only, it stands at its standing height.
    let flat = last_ankle(0.004, false);
    assert!(flat.abs() < 5e-4, "the ankle is {flat} m up");
    // 3 cm up: held at the limit, 0.8 % of the leg.
    let limited = last_ankle(0.03, true);
    assert!(
        (limited - 0.008 * target_leg).abs() < 5e-4,
        "the ankle is {limited} m up, the limit {}",
        0.008 * target_leg
    );
}

/// Standing at 60 Hz; from frame 60 the left foot pitches toes-down about the ankle by up to
/// `pitch_rad` over 20 frames while the body rises so the left toe stays where it stood (the
/// heel coming up off the ground, as it is after a toe-first landing).
fn heel_up(source: &Skeleton, n: usize, pitch_rad: f32) -> Vec<Pose> {
    let rest = source.rest_pose();
    let (foot, toe) = (
        source.bone("l_foot").expect("foot"),
        source.bone("l_toe").expect("toe"),
    );
    let toe_rest = world_transforms(source, &rest)[toe.index()].translation.y;
    (0..n)
        .map(|f| {
            let mut p = rest.clone();
            let k = ((f as f32 - 60.0) / 20.0).clamp(0.0, 1.0);
            p.rotations[foot.index()] =
                rest.rotations[foot.index()] * glam::Quat::from_rotation_x(k * pitch_rad);
            let toe_now = world_transforms(source, &p)[toe.index()].translation.y;
            p.translations[0].y += toe_rest - toe_now;
            p
        })
        .collect()
}

#[test]
fn a_pinned_ankle_follows_the_source_heel_off_the_ground() {
    let (source, target, mapping, lock) = locked_pair();
    let (foot, toe) = (
        target.bone("l_foot").expect("foot"),
        target.bone("l_toe").expect("toe"),
    );
    let rest = world_transforms(&target, &target.rest_pose());
    let (ankle_rest, ball_rest) = (
        rest[foot.index()].translation.y,
        rest[toe.index()].translation.y,
    );
    let scale = mapping.root_scale().expect("a root");
    let target_leg = lock.target_legs().next().expect("a leg").length;
    let legs = lock.source_legs().to_vec();
    let left = legs
        .iter()
        .position(|l| source.name(l.foot).starts_with("l_"))
        .expect("a left leg");
    let poses = heel_up(&source, 120, 0.15);
    let plants = detect_clip(
        &source,
        &legs,
        &poses,
        1.0 / 60.0,
        glam::Vec3::Y,
        &PlantSettings::default(),
    );
    assert_eq!(plants.intervals(left), vec![0..120]);
    let heel = plants.heel_lifts(119)[left];
    assert!(heel > 0.01, "the source's heel is {heel} m up");
    assert!(plants.lifts(119)[left].abs() < 1e-3, "the toe stays down");
    let run = |track: bool| {
        let (mut mapping, mut lock) = (mapping.clone(), lock.clone());
        let mut out = mapping.new_target_pose();
        for (f, p) in poses.iter().enumerate() {
            mapping.apply_one(p, &mut out).expect("apply");
            if track {
                lock.apply_track(&plants, f, 1.0 / 60.0, &mut out);
            } else {
                lock.apply_planted(plants.frame(f), 1.0 / 60.0, &mut out);
            }
        }
        let w = world_transforms(&target, &out);
        (
            w[foot.index()].translation.y - ankle_rest,
            w[toe.index()].translation.y - ball_rest,
        )
    };
    // The ankle comes up with the source's heel above its toe (scaled, at most as far as keeps
    // the ankle-to-ball line half level: sin 60° of the foot's length below the ankle), the
    // ball stays on the floor.
    let foot_lift = plants.lifts(119)[left];
    let lift = (foot_lift * scale).clamp(0.0, 0.008 * target_leg);
    let foot_length = (rest[toe.index()].translation - rest[foot.index()].translation).length();
    let most = (foot_length * 0.75f32.sqrt() - (ankle_rest - ball_rest)).max(0.0);
    let wanted = lift + ((heel - foot_lift.max(0.0)) * scale).clamp(0.0, most);
    let (ankle, ball) = run(true);
    assert!(
        (ankle - wanted).abs() < 1e-3,
        "the ankle is {ankle} m up, the source's heel scaled {wanted}"
    );
    assert!(ball.abs() < 1.5e-3, "the ball is {ball} m up");
    // Given flags only, the foot stays flat where it was pinned.
    let (ankle, _) = run(false);
    assert!(ankle.abs() < 1e-3, "the ankle is {ankle} m up");
}

/// The standard humanoid with its feet hanging from the root (as IK-style game rigs have
/// them), in the same places.
fn detached_feet() -> Skeleton {
    let skel = Humanoid::default().build();
    let rest = world_transforms(&skel, &skel.rest_pose());
    let mut raw = skel.to_raw();
    let root = skel.roots().next().expect("a root");
    let root_raw = raw.bones.iter().position(|b| b.name == skel.name(root));
    for name in ["l_foot", "r_foot"] {
        let b = skel.bone(name).expect(name);
        let (r, f) = (rest[root.index()], rest[b.index()]);
        let bone = raw
            .bones
            .iter_mut()
            .find(|x| x.name == name)
            .expect("a raw foot");
        bone.parent = root_raw;
        bone.rest = Transform {
            translation: r.rotation.inverse() * (f.translation - r.translation),
            rotation: (r.rotation.inverse() * f.rotation).normalize(),
        };
    }
    Skeleton::build(&raw).expect("a skeleton")
}

#[test]
fn a_source_whose_feet_hang_from_the_root_has_its_plants_watched() {
    let skel = detached_feet();
    let analysis = analyze(&SkeletonView::rest(&skel));
    // The IK cannot reach such a foot by bending the leg: not a leg to lock.
    assert!(find_legs(&skel, &analysis).is_empty());
    let legs = find_contact_legs(&skel, &analysis);
    assert_eq!(legs.len(), 2, "{legs:?}");
    let feet: Vec<&str> = legs.iter().map(|l| skel.name(l.foot)).collect();
    assert!(
        feet.contains(&"l_foot") && feet.contains(&"r_foot"),
        "{feet:?}"
    );
    let plants = detect_clip(
        &skel,
        &legs,
        &vec![skel.rest_pose(); 60],
        1.0 / 60.0,
        glam::Vec3::Y,
        &PlantSettings::default(),
    );
    for leg in 0..legs.len() {
        let plants = plants.intervals(leg);
        assert!(plants.len() == 1 && plants[0] == (0..60), "{plants:?}");
    }
}
