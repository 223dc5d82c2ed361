//! A planted foot whose animation points its toes into the floor is pitched up about its
//! ankle, not lifted: the ankle stays where it was pinned, the ball comes up to the floor and
//! the knee keeps its bend (lifting the ankle instead made the knee take up the whole
//! difference, folding the leg over on rigs whose foot points steeply down).

mod retarget_fixtures;

use glam::Quat;
use retarget_fixtures::{table_by_canonical, Humanoid};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings};
use rigcast_retarget::{world_transforms, Mapping, Pose, RetargetOptions, Skeleton};

/// Standing still at 60 Hz; from frame 40 the left foot turns toes-down about the ankle by
/// `pitch_rad` (held), both feet staying planted (the heel does not move).
fn toes_down(source: &Skeleton, num_frames: usize, pitch_rad: f32) -> Vec<Pose> {
    let rest = source.rest_pose();
    let foot = source.bone("l_foot").expect("left foot");
    (0..num_frames)
        .map(|f| {
            let mut p = rest.clone();
            let k = ((f as f32 - 40.0) / 10.0).clamp(0.0, 1.0);
            p.rotations[foot.index()] =
                rest.rotations[foot.index()] * Quat::from_rotation_x(k * pitch_rad);
            p
        })
        .collect()
}

#[test]
fn a_planted_foot_pointing_into_the_floor_is_pitched_up_not_lifted() {
    let source = Humanoid::default().build();
    let target = Humanoid {
        leg: 0.8,
        ..Humanoid::default()
    }
    .build();
    let table = table_by_canonical(&source, "", &target, "");
    let mut mapping =
        Mapping::build(&[&source], &target, &table, &RetargetOptions::default()).expect("build");
    let sa = analyze(&SkeletonView::rest(&source));
    let ta = analyze(&SkeletonView::rest(&target));
    let mut lock =
        FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("a lock for a humanoid");
    let (foot, toe, shin, thigh) = (
        target.bone("l_foot").expect("foot"),
        target.bone("l_toe").expect("toe"),
        target.bone("l_shin").expect("shin"),
        target.bone("l_thigh").expect("thigh"),
    );
    let (_, floor, _) = mapping.target_floor().expect("a floor");
    let rest = world_transforms(&target, &target.rest_pose());
    let toe_standing = rest[toe.index()].translation.y;
    let dt = 1.0 / 60.0;
    let mut out = mapping.new_target_pose();
    let mut free = mapping.new_target_pose();
    let (mut ankle_at_40, mut checked) = (None, 0);
    // Both directions of the sign convention: one of them points the toes into the floor.
    for pitch in [0.6f32, -0.6] {
        lock.reset();
        for (f, p) in toes_down(&source, 120, pitch).iter().enumerate() {
            mapping.apply_one(p, &mut out).expect("apply");
            free.copy_from(&out);
            lock.apply_live(p, true, dt, &mut out);
            let w = world_transforms(&target, &out);
            let wf = world_transforms(&target, &free);
            if f == 40 {
                ankle_at_40 = Some(w[foot.index()].translation);
            }
            let free_toe_low = wf[toe.index()].translation.y < toe_standing - 0.03;
            if f < 60 || !free_toe_low {
                continue;
            }
            checked += 1;
            let ankle = w[foot.index()].translation;
            let start = ankle_at_40.expect("frame 40 seen");
            assert!(
                (ankle - start).length() < 0.005,
                "frame {f}: the ankle moved from {start} to {ankle}"
            );
            let ball = w[toe.index()].translation.y;
            assert!(
                ball >= floor - 0.005,
                "frame {f}: ball {ball} below the floor {floor}"
            );
            // The knee keeps the bend it had (no fold-over): thigh and shin directions stay
            // within a few degrees of the free retarget's.
            for (a, b) in [(thigh, shin), (shin, foot)] {
                let d = |w: &[rigcast_retarget::WorldTransform]| {
                    (w[b.index()].translation - w[a.index()].translation).normalize()
                };
                let deg = d(&w).angle_between(d(&wf)).to_degrees();
                assert!(deg < 5.0, "frame {f}: leg segment turned {deg:.1}°");
            }
        }
    }
    assert!(
        checked > 20,
        "only {checked} frames had the toes in the floor"
    );
}
