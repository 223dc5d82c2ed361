//! How the foot lock keeps feet out of the floor without folding legs over:
//! - a planted foot whose animation points its toes into the floor is pitched up about its
//!   ankle, not lifted: the ankle stays where it was pinned, the ball comes up to the floor and
//!   the knee keeps its bend (lifting the ankle made the knee take up the whole difference,
//!   folding the leg over on rigs whose foot points steeply down);
//! - a character whose animation sinks it on both pinned feet is lifted, legs as animated,
//!   rather than standing on folded knees;
//! - a planted foot with its toes up is stood flat (ball at its standing height);
//! - a foot planted on a clip's first frame is pinned at its standing height at once (after a
//!   reset it blends in again);
//! - a clip's floor ignores a few frames dipping through it;
//! - offline, the animation is fitted to the standing posture first (a landing foot arrives
//!   flat at its standing height);
//! - live, a rest standing along another up than its motion's (no floor placed for it) still
//!   gives the feet their standing pitch;
//! - live, feet whose floor the mapping does not know are pinned where they stand, not at the
//!   floor it gives, learnt over their first stance and held there.

mod retarget_fixtures;

use glam::{Quat, Vec3};
use retarget_fixtures::{locked_pair, table_by_canonical, Humanoid};
use rigcast_retarget::analysis::{analyze, Analysis, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings, PlantTrack};
use rigcast_retarget::{world_transforms, Clip, Mapping, Pose, Skeleton, WorldTransform};

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

/// One 60 Hz frame: `p` retargeted into `free`, and locked into `out`; the target's world
/// transforms of each (locked, free).
fn locked_and_free(
    mapping: &mut Mapping,
    lock: &mut FootLock,
    p: &Pose,
    out: &mut Pose,
    free: &mut Pose,
) -> (Vec<WorldTransform>, Vec<WorldTransform>) {
    mapping.apply_one(p, out).expect("apply");
    free.copy_from(out);
    lock.apply_live(p, true, 1.0 / 60.0, out);
    let target = mapping.target();
    (
        world_transforms(target, out),
        world_transforms(target, free),
    )
}

#[test]
fn a_planted_foot_pointing_into_the_floor_is_pitched_up_not_lifted() {
    let (source, target, mut mapping, mut lock) = locked_pair();
    let (foot, toe, shin, thigh) = (
        target.bone("l_foot").expect("foot"),
        target.bone("l_toe").expect("toe"),
        target.bone("l_shin").expect("shin"),
        target.bone("l_thigh").expect("thigh"),
    );
    let (_, floor, _) = mapping.target_floor().expect("a floor");
    let rest = world_transforms(&target, &target.rest_pose());
    let toe_standing = rest[toe.index()].translation.y;
    let mut out = mapping.new_target_pose();
    let mut free = mapping.new_target_pose();
    let (mut ankle_at_40, mut checked) = (None, 0);
    // Both directions of the sign convention: one of them points the toes into the floor.
    for pitch in [0.6f32, -0.6] {
        lock.reset();
        for (f, p) in toes_down(&source, 120, pitch).iter().enumerate() {
            let (w, wf) = locked_and_free(&mut mapping, &mut lock, p, &mut out, &mut free);
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
                let d = |w: &[WorldTransform]| {
                    (w[b.index()].translation - w[a.index()].translation).normalize_or_zero()
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

/// Standing at 60 Hz; from frame 20 the hips sink `sink` metres with the legs straight (the
/// feet go through the floor, as a capture whose hips track low does).
fn sinking(source: &Skeleton, num_frames: usize, sink: f32) -> Vec<Pose> {
    let rest = source.rest_pose();
    (0..num_frames)
        .map(|f| {
            let mut p = rest.clone();
            let k = ((f as f32 - 20.0) / 10.0).clamp(0.0, 1.0);
            p.translations[0].y -= k * sink;
            p
        })
        .collect()
}

#[test]
fn a_character_sunk_on_both_pinned_feet_is_lifted_not_folded() {
    let (source, target, mut mapping, mut lock) = locked_pair();
    let root = mapping.root_bone().expect("root");
    let legs: Vec<[rigcast_retarget::BoneId; 3]> = ["l", "r"]
        .iter()
        .map(|s| {
            let b = |n: &str| target.bone(&format!("{s}_{n}")).expect("leg bone");
            [b("thigh"), b("shin"), b("foot")]
        })
        .collect();
    let mut out = mapping.new_target_pose();
    let mut free = mapping.new_target_pose();
    let mut pinned_at = Vec::new();
    let mut standing_root = 0.0;
    let mut checked = 0;
    for (f, p) in sinking(&source, 90, 0.05).iter().enumerate() {
        let (w, wf) = locked_and_free(&mut mapping, &mut lock, p, &mut out, &mut free);
        if f == 15 {
            pinned_at = legs.iter().map(|l| w[l[2].index()].translation).collect();
            standing_root = wf[root.index()].translation.y;
        }
        if f < 45 {
            continue;
        }
        checked += 1;
        // The free retarget sank by the source's sink scaled to the target; the lock gives
        // (most of) it back.
        let sunk = standing_root - wf[root.index()].translation.y;
        let lifted = w[root.index()].translation.y - wf[root.index()].translation.y;
        assert!(
            sunk > 0.03,
            "frame {f}: the free retarget sank only {sunk} m"
        );
        assert!(
            lifted > 0.8 * sunk,
            "frame {f}: the hips were lifted {lifted} m of the {sunk} m sunk"
        );
        for (leg, at) in legs.iter().zip(&pinned_at) {
            let ankle = w[leg[2].index()].translation;
            assert!(
                (ankle - *at).length() < 0.005,
                "frame {f}: pinned ankle moved to {ankle}"
            );
            let dir = |w: &[WorldTransform], a: usize, b: usize| {
                (w[leg[b].index()].translation - w[leg[a].index()].translation).normalize_or_zero()
            };
            for (a, b) in [(0, 1), (1, 2)] {
                let deg = dir(&w, a, b).angle_between(dir(&wf, a, b)).to_degrees();
                assert!(
                    deg < 3.0,
                    "frame {f}: a leg segment turned {deg:.1}° (knee folded)"
                );
            }
        }
    }
    assert!(checked > 30);
}

/// A planted foot whose animation lifts its toes (heel down, toes up: the source's foot joints
/// pitch it) is stood flat: the ball comes down to its standing height, the ankle stays pinned.
#[test]
fn a_planted_foot_with_its_toes_up_is_stood_flat() {
    let (source, target, mut mapping, mut lock) = locked_pair();
    let (foot, toe) = (
        target.bone("l_foot").expect("foot"),
        target.bone("l_toe").expect("toe"),
    );
    let rest = world_transforms(&target, &target.rest_pose());
    let toe_standing = rest[toe.index()].translation.y;
    let mut out = mapping.new_target_pose();
    let mut free = mapping.new_target_pose();
    let mut checked = 0;
    // Both directions of the sign convention: one of them lifts the toes.
    for pitch in [0.4f32, -0.4] {
        lock.reset();
        let mut ankle_at_40 = None;
        for (f, p) in toes_down(&source, 150, pitch).iter().enumerate() {
            let (w, wf) = locked_and_free(&mut mapping, &mut lock, p, &mut out, &mut free);
            if f == 40 {
                ankle_at_40 = Some(w[foot.index()].translation);
            }
            let free_toe_up = wf[toe.index()].translation.y > toe_standing + 0.03;
            // After the pitch (frame 50) and the blend.
            if f < 100 || !free_toe_up {
                continue;
            }
            checked += 1;
            let ball = w[toe.index()].translation.y;
            assert!(
                (ball - toe_standing).abs() < 0.005,
                "frame {f}: ball at {ball}, standing height {toe_standing} (free {})",
                wf[toe.index()].translation.y
            );
            let ankle = w[foot.index()].translation;
            let start = ankle_at_40.expect("frame 40 seen");
            assert!(
                (ankle - start).length() < 0.005,
                "frame {f}: the ankle moved from {start} to {ankle}"
            );
        }
    }
    assert!(checked > 20, "only {checked} frames had the toes up");
}

/// A foot planted on the very first frame is pinned at its standing height at once: nothing was
/// shown before it, so there is nothing to blend from. Here the source stands 3 cm above its
/// floor throughout (a capture whose floor sits lower).
#[test]
fn a_foot_planted_on_the_first_frame_is_pinned_at_once() {
    let (source, target, mapping, _) = locked_pair();
    let foot = target.bone("l_foot").expect("foot");
    let rest = world_transforms(&target, &target.rest_pose());
    let ankle_standing = rest[foot.index()].translation.y;
    let mut raised = source.rest_pose();
    raised.translations[0].y += 0.03;
    let frames = vec![raised; 30];
    let planted = [true; 4];
    let mut mapping = mapping;
    let sa = analyze(&SkeletonView::rest(&source));
    let ta = analyze(&SkeletonView::rest(&target));
    let mut lock = FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("lock");
    let mut out = mapping.new_target_pose();
    for (f, p) in frames.iter().enumerate() {
        mapping.apply_one(p, &mut out).expect("apply");
        let animated = world_transforms(&target, &out)[foot.index()].translation.y;
        lock.apply_planted(&planted[..lock.source_legs().len()], 1.0 / 60.0, &mut out);
        let ankle = world_transforms(&target, &out)[foot.index()].translation.y;
        assert!(
            animated > ankle_standing + 0.02,
            "the animated ankle {animated} stands above its height {ankle_standing}"
        );
        assert!(
            (ankle - ankle_standing).abs() < 0.002,
            "frame {f}: the pinned ankle is at {ankle}, its standing height {ankle_standing}"
        );
    }
    // After a reset (a source restarted) the character has been shown: a plant blends in from
    // the animation again, it does not jump.
    lock.reset();
    mapping.apply_one(&frames[0], &mut out).expect("apply");
    let animated = world_transforms(&target, &out)[foot.index()].translation.y;
    lock.apply_planted(&planted[..lock.source_legs().len()], 1.0 / 60.0, &mut out);
    let ankle = world_transforms(&target, &out)[foot.index()].translation.y;
    assert!(
        (ankle - animated).abs() < 0.002,
        "after a reset the ankle starts at the animation's {animated}, not at {ankle}"
    );
}

/// A clip's floor is where its feet usually get lowest: a standing clip whose hips drop 10 cm
/// on two frames of 60 (the feet going through the floor, as a glitch or a toe-off dip does)
/// keeps the standing floor, so the target is not floated above it on every other frame.
#[test]
fn a_clip_floor_ignores_frames_that_dip_through_it() {
    let (source, _, mapping, _) = locked_pair();
    let rest = source.rest_pose();
    let standing = mapping
        .measure_source_floor(std::slice::from_ref(&rest))
        .expect("a floor");
    let mut frames = vec![rest.clone(); 60];
    for f in [20, 41] {
        frames[f].translations[0].y -= 0.10;
    }
    let floor = mapping.measure_source_floor(&frames).expect("a floor");
    assert!(
        (floor - standing).abs() < 0.001,
        "floor {floor} m, the feet stand at {standing} m"
    );
}

/// A clip whose feet stand with their toes 0.3 rad up and the body 3 cm high (as a retarget
/// copying the source's foot direction gives a rig whose foot is built differently), the left
/// foot lifted (hip flexed, foot pitch kept) over frames 40..70; the plants of that clip.
fn toes_up_steps(source: &Skeleton) -> (Vec<Pose>, Vec<bool>) {
    let rest = source.rest_pose();
    let bone = |n: &str| source.bone(n).expect(n).index();
    let (root, l_thigh, l_foot, r_foot) = (0, bone("l_thigh"), bone("l_foot"), bone("r_foot"));
    let mut poses = Vec::new();
    let mut planted = Vec::new();
    for f in 0..120 {
        let mut p = rest.clone();
        p.translations[root].y += 0.03;
        let lift = if (40..70).contains(&f) { 0.4 } else { 0.0 };
        p.rotations[l_thigh] = rest.rotations[l_thigh] * Quat::from_rotation_x(-lift);
        p.rotations[l_foot] = rest.rotations[l_foot] * Quat::from_rotation_x(lift - 0.3);
        p.rotations[r_foot] = rest.rotations[r_foot] * Quat::from_rotation_x(-0.3);
        poses.push(p);
        planted.extend([lift == 0.0, true]);
    }
    (poses, planted)
}

/// Offline, the lock first fits the animation to the character's standing posture: planted
/// feet stand flat at their own heights, a landing foot arrives already flat (no blend across
/// the toes-up gap), and a lifted foot keeps its posture's pitch. Without the fit the landing
/// shows the gap.
#[test]
fn offline_the_animation_is_fitted_to_the_standing_posture() {
    let (source, target, mut mapping, lock) = locked_pair();
    let (poses, flags) = toes_up_steps(&source);
    let legs = lock.source_legs().to_vec();
    let order: Vec<usize> = legs
        .iter()
        .map(|l| usize::from(source.name(l.foot).starts_with("r_")))
        .collect();
    let flags: Vec<bool> = flags
        .chunks(2)
        .flat_map(|f| order.iter().map(move |&i| f[i]))
        .collect();
    let plants = PlantTrack::from_flags(legs, flags);
    let clip = Clip::new(
        "steps",
        std::sync::Arc::new(source.clone()),
        poses,
        1.0 / 60.0,
    )
    .expect("clip");
    let animated = mapping.apply_clip(&clip).expect("retarget");
    let (foot, toe) = (
        target.bone("l_foot").expect("foot"),
        target.bone("l_toe").expect("toe"),
    );
    let rest = world_transforms(&target, &target.rest_pose());
    let (ankle_rest, ball_rest) = (
        rest[foot.index()].translation,
        rest[toe.index()].translation,
    );
    let pitch = |w: &[WorldTransform]| {
        let o = w[toe.index()].translation - w[foot.index()].translation;
        (o.y / o.length()).asin()
    };
    let run = |fit: bool| {
        let mut lock = lock.clone();
        if fit {
            lock.fit_to_standing(&animated.poses, &plants);
        }
        let mut mapping = mapping.clone();
        let mut out = mapping.new_target_pose();
        let mut worlds = Vec::new();
        for (f, p) in clip.poses.iter().enumerate() {
            mapping.apply_one(p, &mut out).expect("apply");
            lock.apply_planted(plants.frame(f), 1.0 / 60.0, &mut out);
            worlds.push(world_transforms(&target, &out));
        }
        worlds
    };
    let fitted = run(true);
    let off_standing = |w: &[WorldTransform]| {
        let a = (w[foot.index()].translation.y - ankle_rest.y).abs();
        let b = (w[toe.index()].translation.y - ball_rest.y).abs();
        a.max(b)
    };
    for (f, w) in fitted.iter().enumerate() {
        if plants.is_planted(f, 0) && plants.is_planted(f, 1) {
            assert!(
                off_standing(w) < 0.005,
                "frame {f}: {} m off",
                off_standing(w)
            );
        }
        if (45..65).contains(&f) {
            let d = (pitch(w) - pitch(&rest)).abs().to_degrees();
            assert!(
                d < 1.0,
                "frame {f}: the lifted foot pitched {d}° off its posture"
            );
        }
    }
    // The plain lock lands the foot with its toes up and flattens it over the blend.
    let plain = run(false);
    let landing = |w: &[Vec<WorldTransform>]| off_standing(&w[70]);
    assert!(
        landing(&plain) > 0.01 && landing(&fitted) < 0.005,
        "landing off standing: {} m plain, {} m fitted",
        landing(&plain),
        landing(&fitted)
    );
}

/// `skel` turned Z-up: its root's rest turned 90° about X (+Y to +Z), as a rig authored in a
/// Z-up tool stands in its file.
fn turned_z_up(skel: &Skeleton) -> Skeleton {
    let turn = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let mut raw = skel.to_raw();
    for b in raw.bones.iter_mut().filter(|b| b.parent.is_none()) {
        b.rest.rotation = turn * b.rest.rotation;
        b.rest.translation = turn * b.rest.translation;
    }
    Skeleton::build(&raw).expect("turned skeleton")
}

/// The setting of the z-up tests: the default humanoid driving a longer-legged one whose rest
/// stands along +Z (`turned_z_up`), mapped by canonical names, with both rests' analyses.
fn z_up_pair() -> (Skeleton, Skeleton, Mapping, (Analysis, Analysis)) {
    let source = Humanoid::default().build();
    let target = turned_z_up(
        &Humanoid {
            leg: 0.8,
            ..Humanoid::default()
        }
        .build(),
    );
    let table = table_by_canonical(&source, "", &target, "");
    let opts = rigcast_retarget::RetargetOptions::default();
    let mapping = Mapping::build(&[&source], &target, &table, &opts).expect("build");
    let analyses = (
        analyze(&SkeletonView::rest(&source)),
        analyze(&SkeletonView::rest(&target)),
    );
    (source, target, mapping, analyses)
}

/// The left foot's ankle-to-ball pitch along `up` in world transforms of `target`, degrees.
fn left_foot_pitch(target: &Skeleton) -> impl Fn(&[WorldTransform], Vec3) -> f32 {
    let (foot, toe) = (
        target.bone("l_foot").expect("foot"),
        target.bone("l_toe").expect("toe"),
    );
    move |w: &[WorldTransform], up: Vec3| {
        let o = w[toe.index()].translation - w[foot.index()].translation;
        (o.dot(up) / o.length()).asin().to_degrees()
    }
}

/// Live, a rig whose rest stands on its own ground along its own up (+Z) under a motion whose up
/// is +Y, so the retarget places no floor for that rest (MakeHuman's case), still gets its feet's
/// standing pitch: the live fit learns it on the planted frames and pitches every frame by it, so
/// a foot lifted with its pitch kept shows the rest's pitch too, read along the animation's up.
/// The answer is the rig's own: its rest's ankle-to-ball pitch along +Z. The performer stands
/// with its toes 0.3 rad up against that (the retargeted foot 17° off it). The pin stands the
/// planted frames at that pitch whatever the fit; the lifted ones show the fit (without it
/// they keep the animation's 17° gap).
#[test]
fn live_a_rest_standing_along_its_own_up_gives_its_feet_pitch() {
    let (source, target, mut mapping, (sa, ta)) = z_up_pair();
    assert!(ta.up.abs_diff_eq(Vec3::Z, 1e-4), "rest up {}", ta.up);
    assert!(
        !mapping.target_posture_stands(),
        "the case: no floor placed for a rest along another up"
    );
    let (up, _, _) = mapping.target_floor().expect("a floor");
    assert!(up.abs_diff_eq(Vec3::Y, 1e-4), "motion up {up}");
    let mut lock = FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("a lock");
    let pitch = left_foot_pitch(&target);
    let standing = pitch(&world_transforms(&target, &target.rest_pose()), Vec3::Z);
    let (poses, _) = toes_up_steps(&source);
    let mut out = mapping.new_target_pose();
    let mut free = mapping.new_target_pose();
    let mut checked = 0;
    for (f, p) in poses.iter().enumerate() {
        let (w, wf) = locked_and_free(&mut mapping, &mut lock, p, &mut out, &mut free);
        // Planted, after the pin has taken the foot; lifted (hip flexed, the foot's pitch kept).
        if (20..40).contains(&f) || (45..65).contains(&f) {
            let (locked, animated) = (pitch(&w, up), pitch(&wf, up));
            assert!(
                (animated - standing).abs() > 10.0,
                "frame {f}: the animation already stands at {animated}°"
            );
            assert!(
                (locked - standing).abs() < 1.0,
                "frame {f}: the foot pitched {locked}°, its rest {standing}° (animated {animated}°)"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 40);
}

/// Standing still at 60 Hz on bent knees (thighs turned `bend` rad, shins back twice that, feet
/// level again), the hips lowered so the toes stand where they stood in the rest.
fn crouching(source: &Skeleton, num_frames: usize, bend: f32) -> Vec<Pose> {
    let mut p = source.rest_pose();
    for side in ["l", "r"] {
        for (bone, angle) in [("thigh", bend), ("shin", -2.0 * bend), ("foot", bend)] {
            let b = source.bone(&format!("{side}_{bone}")).expect("a leg bone");
            p.rotations[b.index()] *= Quat::from_rotation_x(angle);
        }
    }
    let toe = source.bone("l_toe").expect("toe");
    let toe_y = |p: &Pose| world_transforms(source, p)[toe.index()].translation.y;
    p.translations[0].y -= toe_y(&p) - toe_y(&source.rest_pose());
    vec![p; num_frames]
}

/// Where the mapping does not know the character's floor (nothing mapped below its root is
/// below the source's: here the root follows the source's spine, the legs its legs), the
/// floor it gives is the source's scaled, and the retargeted feet may stand far from it (here
/// 1 m above: the source's floor given 1.5 m under its feet, scaled by 0.69). Live, the lock
/// learns where each
/// foot stands from its stance and pins it there: the planted legs keep the source's bent
/// knees. Pinned at the mapping's floor, the legs were stretched towards it.
#[test]
fn live_feet_whose_floor_is_unknown_are_pinned_where_they_stand() {
    use rigcast_retarget::retarget::FloorAt;
    let (source, target, mut mapping, mut lock) = unknown_floor_lock();
    let (_, floor, floor_at) = mapping.target_floor().expect("a floor");
    assert_eq!(floor_at, FloorAt::Unknown, "the mapping knows the floor");
    let bones = |side: &str| {
        ["thigh", "shin", "foot"].map(|b| target.bone(&format!("{side}_{b}")).expect("leg"))
    };
    let (mut out, mut free) = (mapping.new_target_pose(), mapping.new_target_pose());
    let mut checked = 0;
    for (f, p) in crouching(&source, 120, 0.5).iter().enumerate() {
        let (w, wf) = locked_and_free(&mut mapping, &mut lock, p, &mut out, &mut free);
        let ankle = wf[bones("l")[2].index()].translation.y;
        assert!(
            ankle > floor + 0.9,
            "the feet stand at {ankle}, the floor {floor}"
        );
        if f < 30 {
            continue;
        }
        assert!(
            (0..2).all(|i| lock.is_locked(i)),
            "frame {f}: a standing foot is not held"
        );
        for [thigh, shin, foot] in [bones("l"), bones("r")] {
            for (a, b) in [(thigh, shin), (shin, foot)] {
                let d = |w: &[WorldTransform]| {
                    (w[b.index()].translation - w[a.index()].translation).normalize_or_zero()
                };
                let deg = d(&w).angle_between(d(&wf)).to_degrees();
                assert!(deg < 3.0, "frame {f}: a leg segment turned {deg:.1}°");
            }
        }
        checked += 1;
    }
    assert_eq!(checked, 90);
}

/// The lock of [`live_feet_whose_floor_is_unknown_are_pinned_where_they_stand`]: a character
/// whose floor the mapping does not know, its root following the source's spine.
fn unknown_floor_lock() -> (Skeleton, Skeleton, Mapping, FootLock) {
    let source = Humanoid::default().build();
    let target = Humanoid {
        leg: 0.8,
        ..Humanoid::default()
    }
    .build();
    let mut table = table_by_canonical(&source, "", &target, "");
    let is_leg = |name: &str| {
        ["thigh", "shin", "foot", "toe"]
            .iter()
            .any(|l| name.contains(l))
    };
    for t in target.bone_ids() {
        if t == target.bone("hips").expect("hips") || !is_leg(target.name(t)) {
            table.entries[t.index()] = None;
        }
    }
    let mut hips = table_by_canonical(&source, "", &target, "");
    let spine = source.bone("spine").expect("spine");
    let root = target.bone("hips").expect("hips").index();
    table.entries[root] = hips.entries[root].take().map(|mut e| {
        e.sources[0].bone = spine;
        e
    });
    let opts = rigcast_retarget::RetargetOptions {
        source_floor_y: Some(-1.5),
        ..Default::default()
    };
    let mapping = Mapping::build(&[&source], &target, &table, &opts).expect("build");
    let sa = analyze(&SkeletonView::rest(&source));
    let ta = analyze(&SkeletonView::rest(&target));
    let lock = FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("lock");
    (source, target, mapping, lock)
}

/// `crouching`'s pose with the left foot lifted off the floor (hip flexed, knee bent back):
/// the foot swings between two stances.
fn left_foot_lifted(source: &Skeleton, crouch: &Pose) -> Pose {
    let mut p = crouch.clone();
    for (bone, angle) in [("l_thigh", 0.5), ("l_shin", -1.0)] {
        let b = source.bone(bone).expect("a leg bone");
        p.rotations[b.index()] *= Quat::from_rotation_x(angle);
    }
    p
}

/// Live, a foot that learns where it stands learns it over its first stance and holds it:
/// the performer's floor does not move. The left foot stands (1 s on slightly bent knees),
/// swings, and stands again crouched lower (2 s), the source's feet on the floor both times
/// while the retargeted ankle stands at another height on each: the second stance is pinned
/// at the first's height. Learnt from every stance seen, the pin moved towards the second's
/// height as that stance went on: the character's planted feet stood at another height on
/// each stance (live, the pymo Meredith walk onto the CMU 131_01 rig: 3.09 cm off the
/// performer's, 0.96 held).
#[test]
fn live_a_learnt_standing_height_is_held_after_the_first_stance() {
    let (source, target, mut mapping, mut lock) = unknown_floor_lock();
    let ankle = target.bone("l_foot").expect("foot");
    let low = crouching(&source, 1, 0.6).remove(0);
    let poses: Vec<Pose> = (crouching(&source, 60, 0.2).into_iter())
        .chain(std::iter::repeat_n(left_foot_lifted(&source, &low), 30))
        .chain(std::iter::repeat_n(low.clone(), 120))
        .collect();
    let (mut out, mut free) = (mapping.new_target_pose(), mapping.new_target_pose());
    let mut shown = Vec::new();
    let mut animated = Vec::new();
    let mut held = Vec::new();
    for p in &poses {
        let (w, wf) = locked_and_free(&mut mapping, &mut lock, p, &mut out, &mut free);
        shown.push(w[ankle.index()].translation.y);
        animated.push(wf[ankle.index()].translation.y);
        held.push(lock.is_locked(0));
    }
    assert!(
        held[59] && !held[75] && held[209],
        "the left foot stands, swings, stands"
    );
    let apart = (animated[209] - animated[59]).abs();
    assert!(
        apart > 0.01,
        "the stances' animated heights differ by {apart:.4} m"
    );
    let off = (shown[209] - shown[59]).abs() / apart;
    assert!(
        off < 0.05,
        "pinned at {:.4} on the first stance, {:.4} on the second (animated {:.4}, {:.4}): \
         {:.0} % of their difference apart",
        shown[59],
        shown[209],
        animated[59],
        animated[209],
        off * 100.0
    );
}

/// The setting the live pitch tests share: [`z_up_pair`] with a live lock on it, the motion's
/// up, the left foot's rest pitch (°, read along +Z), the source's rest pose and its left thigh,
/// left foot and right foot.
struct LiveLegs {
    target: Skeleton,
    mapping: Mapping,
    lock: FootLock,
    up_and_standing: (Vec3, f32),
    rest: Pose,
    bones: (usize, usize, usize),
}

fn live_legs() -> LiveLegs {
    let (source, target, mapping, (sa, ta)) = z_up_pair();
    let lock = FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("a lock");
    let (up, _, _) = mapping.target_floor().expect("a floor");
    let standing =
        left_foot_pitch(&target)(&world_transforms(&target, &target.rest_pose()), Vec3::Z);
    let bone = |n: &str| source.bone(n).expect(n).index();
    LiveLegs {
        up_and_standing: (up, standing),
        rest: source.rest_pose(),
        bones: (bone("l_thigh"), bone("l_foot"), bone("r_foot")),
        target,
        mapping,
        lock,
    }
}

/// The source's left leg lifted at frame `f`: the hip flexed, swinging in a small circle
/// (never slow enough to stand), the performer's toes kept 0.3 rad up.
fn swing_left_leg(p: &mut Pose, rest: &Pose, (l_thigh, l_foot): (usize, usize), f: usize) {
    let (a, t) = (0.1, f as f32 * std::f32::consts::TAU * 2.0 / 60.0);
    let swing = Quat::from_rotation_z(a * t.cos()) * Quat::from_rotation_x(-0.4 + a * t.sin());
    p.rotations[l_thigh] = rest.rotations[l_thigh] * swing;
    let kept = Quat::from_rotation_x(0.4 - a * t.sin() - 0.3);
    p.rotations[l_foot] = rest.rotations[l_foot] * kept;
}

/// At frame `f`, a lifted foot shows its rest's pitch `standing` (within 1.5°) while the
/// animation's stands more than 10° from it (°, shown and animated).
fn assert_rest_pitch(f: usize, (shown, animated): (f32, f32), standing: f32) {
    assert!(
        (animated - standing).abs() > 10.0,
        "frame {f}: the animation already stands at {animated}°"
    );
    assert!(
        (shown - standing).abs() < 1.5,
        "frame {f}: the lifted foot pitched {shown}°, its rest {standing}° (animated \
         {animated}°)"
    );
}

/// Live, a foot that has not stood yet takes the pitch fit its fellow foot has learnt: the
/// character's feet are built alike. The setting of
/// [`live_a_rest_standing_along_its_own_up_gives_its_feet_pitch`], with the left foot lifted
/// from the first frame (hip flexed, swinging in a small circle, the performer's toes 0.3 rad
/// up kept) while the right stands: once the right foot has learnt the fit, the lifted left foot shows its rest's pitch
/// (the rig's own answer, read along +Z in its rest), not the animation's 17° gap. Left at no
/// fit until it stood itself, a foot's first plant pitched it from the performer's pitch to
/// its own over a blend's time (the CMU walk onto X Bot: the second foot's toes 5 cm up).
#[test]
fn live_a_foot_not_yet_stood_takes_its_fellow_foot_fit() {
    let LiveLegs {
        target,
        mut mapping,
        mut lock,
        up_and_standing: (up, standing),
        rest,
        bones: (l_thigh, l_foot, r_foot),
    } = live_legs();
    let pitch = left_foot_pitch(&target);
    let (mut out, mut free) = (mapping.new_target_pose(), mapping.new_target_pose());
    let mut checked = 0;
    for f in 0..60 {
        let mut p = rest.clone();
        p.translations[0].y += 0.03;
        swing_left_leg(&mut p, &rest, (l_thigh, l_foot), f);
        p.rotations[r_foot] = rest.rotations[r_foot] * Quat::from_rotation_x(-0.3);
        let (w, wf) = locked_and_free(&mut mapping, &mut lock, &p, &mut out, &mut free);
        if f >= 20 {
            assert_rest_pitch(f, (pitch(&w, up), pitch(&wf, up)), standing);
            checked += 1;
        }
    }
    let foot = target.bone("l_foot").expect("foot");
    let left = lock.target_legs().position(|l| l.foot == foot);
    assert!(
        !lock.is_locked(left.expect("the left leg")),
        "the lifted foot is held"
    );
    assert_eq!(checked, 40);
}

/// Live, a foot's pitch fit is the median over all it has stood (its frames on the ball alone
/// aside), as offline reads it off the whole clip: a rig's foot is built one way for the whole
/// performance, and the performer's stance pitch wanders about it (Xia's walk: its planted
/// foot 12-24° down over one stance as its heel rises within the detector's bound). The
/// setting of [`live_a_foot_not_yet_stood_takes_its_fellow_foot_fit`]: both feet stand with
/// the performer's toes 0.3 rad up for a second, then 0.1 rad up for half a second, then the
/// left foot lifts with its toes 0.3 rad up again: it shows its rest's pitch, the fit of most
/// of its stance. A running average over the last second (as before) had moved most of the
/// way to the last half second's fit, tipping the lifted foot by several degrees.
#[test]
fn live_a_foot_pitch_fit_is_the_median_of_its_stances() {
    let LiveLegs {
        target,
        mut mapping,
        mut lock,
        up_and_standing: (up, standing),
        rest,
        bones: (l_thigh, l_foot, r_foot),
    } = live_legs();
    let pitch = left_foot_pitch(&target);
    let (mut out, mut free) = (mapping.new_target_pose(), mapping.new_target_pose());
    let mut checked = 0;
    for f in 0..150 {
        let mut p = rest.clone();
        p.translations[0].y += 0.03;
        // Toes 0.3 rad up, coming down to 0.1 over frames 60-80 (slowly enough to stand).
        let toes = 0.3 - 0.2 * ((f as f32 - 60.0) / 20.0).clamp(0.0, 1.0);
        p.rotations[r_foot] = rest.rotations[r_foot] * Quat::from_rotation_x(-toes);
        if f < 90 {
            p.rotations[l_foot] = rest.rotations[l_foot] * Quat::from_rotation_x(-toes);
        } else {
            swing_left_leg(&mut p, &rest, (l_thigh, l_foot), f);
        }
        let (w, wf) = locked_and_free(&mut mapping, &mut lock, &p, &mut out, &mut free);
        if f >= 110 {
            assert_rest_pitch(f, (pitch(&w, up), pitch(&wf, up)), standing);
            checked += 1;
        }
    }
    assert_eq!(checked, 40);
}
