//! Per-bone options and build-time validation of `Mapping`: many-to-one blending (weighted,
//! sign-aligned), delay, reverse, weight, unmapped bones at rest, a representative reference
//! pose for rests that are not the posture to align, and clear errors for bad input.

mod retarget_fixtures;

use glam::{Quat, Vec3};
use retarget_fixtures::{bone, motion, table_by_canonical, Axes, Humanoid};
use rigcast_retarget::approx::{quat_angle, quat_close};
use rigcast_retarget::mapping::{BoneOptions, MappingTable, SourceRef, TargetEntry};
use rigcast_retarget::{
    world_transforms, BoneId, Mapping, Pose, RawSkeleton, RetargetError, RetargetOptions, Skeleton,
    Transform,
};

/// root → arm → hand → tip, arm along +X.
fn arm() -> Skeleton {
    let mut raw = RawSkeleton::default();
    let root = raw.add("root", None, Transform::from_translation(Vec3::Y));
    let arm = raw.add(
        "arm",
        Some(root),
        Transform::from_translation(Vec3::X * 0.1),
    );
    let hand = raw.add(
        "hand",
        Some(arm),
        Transform::from_translation(Vec3::X * 0.3),
    );
    raw.add(
        "tip",
        Some(hand),
        Transform::from_translation(Vec3::X * 0.1),
    );
    Skeleton::build(&raw).expect("arm")
}

fn entry(sources: Vec<SourceRef>, options: BoneOptions) -> Option<TargetEntry> {
    Some(TargetEntry {
        sources,
        options,
        score: 0.0,
        evidence: vec![],
        confidence: 1.0,
    })
}

fn one(input: u16, bone: u16) -> SourceRef {
    SourceRef {
        input,
        bone: BoneId(bone),
        weight: 1.0,
    }
}

/// Identity table for the arm, `options` on the arm bone.
fn arm_table(options: BoneOptions) -> MappingTable {
    let mut t = MappingTable::empty(4);
    for b in 0..4u16 {
        let o = if b == 1 {
            options
        } else {
            BoneOptions::default()
        };
        t.entries[b as usize] = entry(vec![one(0, b)], o);
    }
    t
}

fn posed(skel: &Skeleton, arm_rotation: Quat) -> Pose {
    let mut p = skel.rest_pose();
    p.rotations[1] = arm_rotation;
    p
}

fn world_rotation(skel: &Skeleton, pose: &Pose, b: usize) -> Quat {
    world_transforms(skel, pose)[b].rotation
}

#[test]
fn many_to_one_blends_weighted_and_sign_aligned() {
    let s = arm();
    let mut table = arm_table(BoneOptions::default());
    let blend = |wa: f32, wb: f32| {
        vec![
            SourceRef {
                input: 0,
                bone: BoneId(1),
                weight: wa,
            },
            SourceRef {
                input: 1,
                bone: BoneId(1),
                weight: wb,
            },
        ]
    };
    table.entries[1] = entry(blend(1.0, 1.0), BoneOptions::default());
    let mut m = Mapping::build(&[&s, &s], &s, &table, &RetargetOptions::default()).expect("build");
    let a = posed(&s, Quat::from_rotation_z(1.2));
    // The same rotation as identity, stored with the opposite sign: blending must not care.
    let b = posed(&s, -Quat::IDENTITY);
    let mut out = s.rest_pose();
    m.apply(&[&a, &b], &mut out).expect("apply");
    let got = world_rotation(&s, &out, 1);
    assert!(
        quat_close(got, Quat::from_rotation_z(0.6), 2e-3),
        "equal weights: {got}"
    );

    // Unequal weights: the normalised weighted average (nlerp), not either input.
    table.entries[1] = entry(blend(3.0, 1.0), BoneOptions::default());
    let mut m = Mapping::build(&[&s, &s], &s, &table, &RetargetOptions::default()).expect("build");
    m.apply(&[&a, &b], &mut out).expect("apply");
    let expected = (Quat::from_rotation_z(1.2) * 0.75 + Quat::IDENTITY * 0.25).normalize();
    let got = world_rotation(&s, &out, 1);
    assert!(quat_close(got, expected, 2e-3), "{got} vs {expected}");
    assert!(quat_angle(got, Quat::from_rotation_z(0.9)) < 0.05);
}

#[test]
fn delay_plays_a_bone_late_by_whole_frames() {
    let s = arm();
    let opts = RetargetOptions {
        frame_time_secs: 1.0 / 60.0,
        ..RetargetOptions::default()
    };
    let delayed = BoneOptions {
        delay_secs: 3.0 / 60.0,
        ..BoneOptions::default()
    };
    let mut late = Mapping::build(&[&s], &s, &arm_table(delayed), &opts).expect("build");
    let mut now =
        Mapping::build(&[&s], &s, &arm_table(BoneOptions::default()), &opts).expect("build");
    let frames: Vec<Pose> = (0..20)
        .map(|f| posed(&s, Quat::from_rotation_z(0.1 * f as f32)))
        .collect();
    let mut out_late = s.rest_pose();
    let mut out_now = s.rest_pose();
    let mut history = Vec::new();
    for (f, p) in frames.iter().enumerate() {
        late.apply_one(p, &mut out_late).expect("apply");
        now.apply_one(p, &mut out_now).expect("apply");
        history.push(world_rotation(&s, &out_now, 1));
        // Before three frames have passed, the first frame fills the history.
        let expected = history[f.saturating_sub(3)];
        let got = world_rotation(&s, &out_late, 1);
        assert!(
            quat_close(got, expected, 2e-3),
            "frame {f}: {got} vs {expected}"
        );
        // The hand is not delayed: it keeps following the source in world space.
        let (a, b) = (
            world_rotation(&s, &out_late, 2),
            world_rotation(&s, &out_now, 2),
        );
        assert!(
            quat_close(a, b, 2e-3),
            "frame {f}: hand {a} vs {b}, {}",
            quat_angle(a, b)
        );
    }
    // Reset forgets the past: the next frame fills the history again.
    late.reset();
    late.apply_one(&frames[0], &mut out_late).expect("apply");
    assert!(quat_close(
        world_rotation(&s, &out_late, 1),
        history[0],
        2e-3
    ));
}

#[test]
fn reverse_weight_and_unmapped() {
    let s = arm();
    let q = Quat::from_rotation_z(0.8);
    let source = posed(&s, q);
    let mut out = s.rest_pose();
    // The source retargeted onto its own skeleton with `bone` on the elbow.
    let apply = |bone: BoneOptions, out: &mut Pose| {
        let mut m = Mapping::build(&[&s], &s, &arm_table(bone), &RetargetOptions::default())
            .expect("build");
        m.apply_one(&source, out).expect("apply");
    };

    let reverse = BoneOptions {
        reverse: true,
        ..BoneOptions::default()
    };
    apply(reverse, &mut out);
    assert!(
        quat_close(out.rotations[1], q.inverse(), 2e-3),
        "reversed: {}",
        out.rotations[1]
    );

    let half = BoneOptions {
        weight: 0.5,
        ..BoneOptions::default()
    };
    apply(half, &mut out);
    assert!(quat_close(
        out.rotations[1],
        Quat::from_rotation_z(0.4),
        2e-3
    ));

    let off = BoneOptions {
        weight: 0.0,
        ..BoneOptions::default()
    };
    apply(off, &mut out);
    assert!(quat_close(out.rotations[1], Quat::IDENTITY, 2e-3));

    let mut table = arm_table(BoneOptions::default());
    table.entries[1] = None;
    let mut m = Mapping::build(&[&s], &s, &table, &RetargetOptions::default()).expect("build");
    assert_eq!(m.num_mapped(), 3);
    m.apply_one(&source, &mut out).expect("apply");
    assert!(quat_close(out.rotations[1], s.rest()[1].rotation, 2e-3));
    // Mapped children keep following the source in world space.
    assert!(quat_close(world_rotation(&s, &out, 2), q, 2e-3));
}

#[test]
fn bad_input_is_an_error() {
    let s = arm();
    let ok = arm_table(BoneOptions::default());
    let opts = RetargetOptions::default();
    let short = MappingTable::empty(2);
    assert!(matches!(
        Mapping::build(&[&s], &s, &short, &opts),
        Err(RetargetError::InvalidMapping { .. })
    ));
    assert!(matches!(
        Mapping::build(&[], &s, &ok, &opts),
        Err(RetargetError::InvalidMapping { .. })
    ));
    let mut bad_input = ok.clone();
    bad_input.entries[1] = entry(vec![one(3, 1)], BoneOptions::default());
    assert!(Mapping::build(&[&s], &s, &bad_input, &opts).is_err());
    let wrong_reference = RetargetOptions {
        target_reference: Some(Pose {
            rotations: vec![Quat::IDENTITY],
            translations: vec![Vec3::ZERO],
        }),
        ..RetargetOptions::default()
    };
    assert!(matches!(
        Mapping::build(&[&s], &s, &ok, &wrong_reference),
        Err(RetargetError::PoseSizeMismatch { .. })
    ));
    let bad_time = RetargetOptions {
        frame_time_secs: 0.0,
        ..RetargetOptions::default()
    };
    assert!(Mapping::build(&[&s], &s, &ok, &bad_time).is_err());

    let mut m = Mapping::build(&[&s], &s, &ok, &opts).expect("build");
    let tiny = Pose {
        rotations: vec![Quat::IDENTITY],
        translations: vec![Vec3::ZERO],
    };
    let mut out = s.rest_pose();
    assert!(matches!(
        m.apply_one(&tiny, &mut out),
        Err(RetargetError::PoseSizeMismatch { .. })
    ));
    assert!(m.apply(&[], &mut out).is_err());
    let mut small_out = tiny.clone();
    assert!(m.apply_one(&s.rest_pose(), &mut small_out).is_err());
}

/// A source whose rest is not the posture to align: legs folded up (turned 180° about the
/// side axis, so the feet point backwards) and arms raised. With its T-pose given as the
/// reference, thighs and feet twist like the source's; from the bare rest the thighs come out
/// rolled half a turn (directions alone still match, thanks to the segment fix).
#[test]
fn representative_reference_pose_fixes_twist() {
    let sp = Humanoid::default();
    let t_pose = sp.build();
    // Fold: same joints, rest rotations turn the limbs.
    let fold = |name: &str| -> Quat {
        match name {
            "l_thigh" | "r_thigh" => Quat::from_rotation_x(std::f32::consts::PI),
            "l_upper_arm" => Quat::from_rotation_z(1.4),
            "r_upper_arm" => Quat::from_rotation_z(-1.4),
            _ => Quat::IDENTITY,
        }
    };
    let mut raw = t_pose.to_raw();
    for b in &mut raw.bones {
        b.rest.rotation = fold(&b.name) * b.rest.rotation;
    }
    let folded = Skeleton::build(&raw).expect("folded");
    // The reference undoes the fold: the T-pose, expressed on the folded skeleton.
    let mut reference = folded.rest_pose();
    for b in folded.bone_ids() {
        reference.rotations[b.index()] =
            fold(folded.name(b)).inverse() * folded.rest()[b.index()].rotation;
    }
    // Poses hold full local rotations and the joints are the same, so the T-pose skeleton's
    // motion plays unchanged on the folded one.
    let frames: Vec<Pose> = motion(&t_pose, 60, 0.0, 1.0);
    let tp = Humanoid {
        arm_down_deg: 45.0,
        axes: Axes::AlongBone { roll_rad: 0.2 },
        ..Humanoid::default()
    };
    let target = tp.build();
    let table = table_by_canonical(&folded, "", &target, "");
    let twist_error = |opts: &RetargetOptions| -> f32 {
        let mut m = Mapping::build(&[&folded], &target, &table, opts).expect("build");
        let src_ref = world_transforms(
            &folded,
            opts.source_reference[0].as_ref().unwrap_or(&reference),
        );
        let tgt_aligned = world_transforms(&target, &m.aligned_rest_pose());
        let mut out = target.rest_pose();
        let mut worst = 0.0f32;
        for p in &frames {
            m.apply_one(p, &mut out).expect("apply");
            let ws = world_transforms(&folded, p);
            let wt = world_transforms(&target, &out);
            for n in ["l_thigh", "r_thigh", "l_foot", "l_upper_arm", "l_hand"] {
                let (s, t) = (bone(&folded, "", n).index(), bone(&target, "", n).index());
                let ds = ws[s].rotation * src_ref[s].rotation.inverse();
                let dt = wt[t].rotation * tgt_aligned[t].rotation.inverse();
                worst = worst.max(quat_angle(ds, dt).to_degrees());
            }
        }
        worst
    };
    let with_reference = RetargetOptions {
        source_reference: vec![Some(reference.clone())],
        ..RetargetOptions::default()
    };
    let good = twist_error(&with_reference);
    assert!(good < 1.0, "with the reference pose: {good}°");
    let bare = RetargetOptions {
        source_reference: vec![None],
        ..RetargetOptions::default()
    };
    let bad = twist_error(&bare);
    println!("twist error: with reference {good:.3}°, from the folded rest {bad:.1}°");
    assert!(
        bad > 90.0,
        "the folded rest should mislead twist, got {bad}°"
    );
}

#[test]
fn absurd_delays_are_capped_not_allocated() {
    // An infinite maximum and a billion-second delay must not size a history ring from them;
    // the delay is capped, so the bone keeps showing the first frame (which fills the history).
    let s = arm();
    let opts = RetargetOptions {
        max_delay_secs: f32::INFINITY,
        ..RetargetOptions::default()
    };
    let delayed = BoneOptions {
        delay_secs: 1e9,
        ..BoneOptions::default()
    };
    let mut m = Mapping::build(&[&s], &s, &arm_table(delayed), &opts).expect("build");
    let mut out = s.rest_pose();
    m.apply_one(&posed(&s, Quat::from_rotation_z(0.5)), &mut out)
        .expect("apply");
    let first = world_rotation(&s, &out, 1);
    for f in 1..10 {
        m.apply_one(
            &posed(&s, Quat::from_rotation_z(0.5 + 0.1 * f as f32)),
            &mut out,
        )
        .expect("apply");
        assert!(
            quat_close(world_rotation(&s, &out, 1), first, 2e-3),
            "frame {f}"
        );
    }
}
