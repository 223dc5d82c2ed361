//! Acceptance (issue 13): steady-state foot locking (`FootLock::apply_live`: causal plant
//! detection, locks blending in and out, the hips lowered for a leg that cannot reach, the
//! two-bone IK) allocates nothing — counted with a global allocator, over frames that go
//! through every one of those paths (checked, so the count is not of an idle lock).

mod alloc_count;
mod retarget_fixtures;

use glam::{Quat, Vec3};
use retarget_fixtures::{table_by_canonical, Axes, Humanoid};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings};
use rigcast_retarget::{world_transforms, Mapping, Pose, RetargetOptions, Skeleton};

use alloc_count::allocations;

/// Source frames at 60 Hz: standing (both feet planted), the hips rising 2 cm (the planted
/// feet stay, the legs must stretch), then the left leg swinging forward and back (its plant
/// released and taken again).
fn stepping(source: &Skeleton, num_frames: usize) -> Vec<Pose> {
    let rest = source.rest_pose();
    let thigh = source.bone("l_thigh").expect("left thigh");
    (0..num_frames)
        .map(|f| {
            let mut p = rest.clone();
            let rise = ((f as f32 - 20.0) / 10.0).clamp(0.0, 1.0) * 0.02;
            p.translations[0] += Vec3::Y * rise;
            if (60..90).contains(&f) {
                let swing = ((f - 60) as f32 / 30.0 * std::f32::consts::PI).sin() * 0.6;
                p.rotations[thigh.index()] =
                    rest.rotations[thigh.index()] * Quat::from_rotation_x(-swing);
            }
            p
        })
        .collect()
}

#[test]
fn steady_state_foot_lock_allocates_nothing() {
    let source = Humanoid::default().build();
    let target = Humanoid {
        leg: 0.8,
        axes: Axes::AlongBone { roll_rad: 0.2 },
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
    assert_eq!(lock.target_legs().count(), 2);
    let frames = stepping(&source, 120);
    let dt = 1.0 / 60.0;
    let mut out = mapping.new_target_pose();
    let mut plain = mapping.new_target_pose();
    // Warm-up: the detector's window fills.
    for p in &frames[..5] {
        mapping.apply_one(p, &mut out).expect("apply");
        lock.apply_live(p, true, dt, &mut out);
    }
    let (mut locked_frames, mut released_frames, mut hips_lowered) = (0, 0, 0);
    let mut counted = 0;
    // (The positions below are read outside the counted calls.)
    let foot = target.bone("l_foot").expect("left foot");
    let mut ankle_at = Vec::new();
    for p in &frames[5..] {
        mapping.apply_one(p, &mut out).expect("apply");
        plain.copy_from(&out);
        let before = allocations();
        lock.apply_live(p, true, dt, &mut out);
        counted += allocations() - before;
        locked_frames += usize::from(lock.is_locked(0) && lock.is_locked(1));
        released_frames += usize::from(!lock.is_locked(0) || !lock.is_locked(1));
        let root = mapping.root_bone().expect("root").index();
        hips_lowered += usize::from(out.translations[root].y < plain.translations[root].y - 1e-4);
        ankle_at.push(world_transforms(&target, &out)[foot.index()].translation);
    }
    // The hips rose 2 cm (frames 20–30) but the planted foot stayed where it stood.
    let (standing, risen) = (ankle_at[15 - 5], ankle_at[50 - 5]);
    assert!((standing - risen).length() < 1e-3, "{standing} → {risen}");
    assert_eq!(counted, 0, "the foot lock allocated {counted} times");
    // Every path ran: locks held, a release (the swing), the hips came down for the rise.
    assert!(
        locked_frames > 40,
        "{locked_frames} frames with both feet locked"
    );
    assert!(
        released_frames > 10,
        "{released_frames} frames with a foot released"
    );
    assert!(
        hips_lowered > 10,
        "{hips_lowered} frames with the hips lowered"
    );
    // The counter works.
    let before = allocations();
    let _w = world_transforms(&target, &out);
    assert!(allocations() > before);
}
