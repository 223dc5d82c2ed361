//! A planted foot's clearance: the plants of a clip say how high each foot stands above its
//! ground, and offline the lock holds a pinned target foot as far above its standing height as
//! that, scaled, up to a limit (a foot farther up is landing, or on ground of its own).

mod retarget_fixtures;

use retarget_fixtures::{table_by_canonical, Humanoid};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{detect_clip, FootLock, LockSettings, PlantSettings};
use rigcast_retarget::{world_transforms, Mapping, Pose, RetargetOptions, Skeleton};

/// The standard humanoid driving a shorter-legged one, and the foot lock between them.
fn locked_pair() -> (Skeleton, Skeleton, Mapping, FootLock) {
    let source = Humanoid::default().build();
    let target = Humanoid {
        leg: 0.8,
        ..Humanoid::default()
    }
    .build();
    let table = table_by_canonical(&source, "", &target, "");
    let mapping =
        Mapping::build(&[&source], &target, &table, &RetargetOptions::default()).expect("build");
    let sa = analyze(&SkeletonView::rest(&source));
    let ta = analyze(&SkeletonView::rest(&target));
    let lock =
        FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("a lock for a humanoid");
    (source, target, mapping, lock)
}

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
