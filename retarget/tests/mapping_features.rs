//! Mapper features: axes never assumed, degenerate rests, mirror, many-to-one, per-bone
//! options, mapping files, cache keys, colours, humanoid roles.
#![allow(clippy::unwrap_used)] // tests may unwrap

use glam::{Quat, Vec3};
use rigcast_retarget::analysis::{analyze, humanoid_roles, HumanBone, SkeletonView};
use rigcast_retarget::corpus::{self, CorpusEntry};
use rigcast_retarget::mapping::{
    apply_overrides, auto_map, auto_map_many, cache, file, mapping_colors, parse_mapping_file,
    to_mapping_file, BoneOptions, CacheKey, MapOptions, MappingCache, MappingFileError,
    MappingTable,
};
use rigcast_retarget::{Pose, RawSkeleton, Skeleton};

fn entry(name: &str) -> CorpusEntry {
    corpus::get(name).unwrap_or_else(|| panic!("corpus entry {name}"))
}

/// Primary source label for the target bone labelled `label`.
/// [`auto_map`] of `src` onto `tgt`, both at rest.
fn map_at_rest(src: &Skeleton, tgt: &Skeleton, opts: &MapOptions) -> MappingTable {
    auto_map(&SkeletonView::rest(src), &SkeletonView::rest(tgt), opts)
}

fn mapped_label(
    src: &CorpusEntry,
    tgt: &CorpusEntry,
    table: &MappingTable,
    label: &str,
) -> Option<String> {
    let t = tgt.labels.iter().position(|l| l == label)?;
    let p = table.entries[t].as_ref()?.primary()?;
    Some(src.labels[p.bone.index()].clone())
}

fn rotate_root(skel: &Skeleton, rot: Quat) -> Skeleton {
    let mut raw: RawSkeleton = skel.to_raw();
    for b in raw.bones.iter_mut().filter(|b| b.parent.is_none()) {
        b.rest.rotation = rot * b.rest.rotation;
        b.rest.translation = rot * b.rest.translation;
    }
    Skeleton::build(&raw).unwrap()
}

const CORE_LABELS: &[&str] = &[
    "hips",
    "spine",
    "chest",
    "neck",
    "head",
    "left_upper_arm",
    "right_upper_arm",
    "left_lower_arm",
    "right_lower_arm",
    "left_hand",
    "right_hand",
    "left_upper_leg",
    "right_upper_leg",
    "left_foot",
    "right_foot",
];

#[test]
fn z_up_and_sideways_facing_are_inferred() {
    let src = entry("mixamo");
    for (rot, up, fwd) in [
        // Y-up → Z-up (Blender-like): +Y goes to +Z, +Z (forward) goes to -Y.
        (Quat::from_rotation_x(90f32.to_radians()), Vec3::Z, -Vec3::Y),
        // Facing +X instead of +Z.
        (Quat::from_rotation_y(90f32.to_radians()), Vec3::Y, Vec3::X),
    ] {
        let mut tgt = entry("vrm_anon");
        tgt.skeleton = rotate_root(&tgt.skeleton, rot);
        let a = analyze(&SkeletonView::rest(&tgt.skeleton));
        assert!(a.up.dot(up) > 0.99, "up {:?} expected {up:?}", a.up);
        assert!(
            a.forward.dot(fwd) > 0.95,
            "forward {:?} expected {fwd:?}",
            a.forward
        );
        let table = map_at_rest(&src.skeleton, &tgt.skeleton, &MapOptions::default());
        for l in CORE_LABELS {
            assert_eq!(
                mapped_label(&src, &tgt, &table, l).as_deref(),
                Some(*l),
                "rotated target {rot:?}"
            );
        }
    }
}

#[test]
fn degenerate_rest_uses_the_representative_pose() {
    let real = entry("cmu_cgspeed_anon");
    // Every rest offset collapsed onto +Y (lengths kept): the rest pose is a vertical line.
    let mut raw = real.skeleton.to_raw();
    for b in raw.bones.iter_mut() {
        b.rest.translation = Vec3::Y * b.rest.translation.length();
        b.rest.rotation = Quat::IDENTITY;
    }
    let degenerate = Skeleton::build(&raw).unwrap();
    let frame = Pose {
        rotations: real.skeleton.rest().iter().map(|t| t.rotation).collect(),
        translations: real.skeleton.rest().iter().map(|t| t.translation).collect(),
    };
    let without = analyze(&SkeletonView::rest(&degenerate));
    assert!(!without.used_pose);
    let with = analyze(&SkeletonView::with_pose(&degenerate, Some(&frame)));
    assert!(with.used_pose);
    let tgt = CorpusEntry {
        skeleton: degenerate.clone(),
        ..real.clone()
    };
    let src = entry("mixamo");
    let table = auto_map(
        &SkeletonView::rest(&src.skeleton),
        &SkeletonView::with_pose(&degenerate, Some(&frame)),
        &MapOptions::default(),
    );
    for l in CORE_LABELS {
        assert_eq!(mapped_label(&src, &tgt, &table, l).as_deref(), Some(*l));
    }
}

#[test]
fn mirror_flips_the_front_legs_of_a_quadruped() {
    let src = entry("mixamo");
    let tgt = entry("horse");
    let opts = MapOptions {
        mirror: true,
        ..MapOptions::default()
    };
    let table = map_at_rest(&src.skeleton, &tgt.skeleton, &opts);
    assert_eq!(
        mapped_label(&src, &tgt, &table, "left_upper_arm").as_deref(),
        Some("right_upper_arm")
    );
    assert_eq!(
        mapped_label(&src, &tgt, &table, "right_lower_arm").as_deref(),
        Some("left_lower_arm")
    );
    // Hind legs keep their side.
    assert_eq!(
        mapped_label(&src, &tgt, &table, "left_upper_leg").as_deref(),
        Some("left_upper_leg")
    );
    let plain = map_at_rest(&src.skeleton, &tgt.skeleton, &MapOptions::default());
    assert_eq!(
        mapped_label(&src, &tgt, &plain, "left_upper_arm").as_deref(),
        Some("left_upper_arm")
    );
}

#[test]
fn many_to_one_with_preference_and_blending() {
    let a = entry("mixamo");
    let b = entry("vrm");
    let tgt = entry("unreal");
    let views = [
        SkeletonView::rest(&a.skeleton),
        SkeletonView::rest(&b.skeleton),
    ];
    let prefer_b = MapOptions {
        preferred_source: Some(1),
        ..MapOptions::default()
    };
    let table = auto_map_many(&views, &SkeletonView::rest(&tgt.skeleton), &prefer_b);
    let t = tgt.skeleton.bone("upperarm_l").unwrap();
    let e = table.get(t).unwrap();
    assert_eq!(e.primary().unwrap().input, 1);
    assert_eq!(
        b.labels[e.primary().unwrap().bone.index()],
        "left_upper_arm"
    );
    table
        .validate(&[&a.skeleton, &b.skeleton], &tgt.skeleton)
        .unwrap();

    let blend = MapOptions {
        blend_sources: true,
        remove_duplicates: false,
        ..MapOptions::default()
    };
    let table = auto_map_many(&views, &SkeletonView::rest(&tgt.skeleton), &blend);
    let e = table.get(t).unwrap();
    assert_eq!(e.sources.len(), 2, "{:?}", e.sources);
    assert_ne!(e.sources[0].input, e.sources[1].input);
    for s in &e.sources {
        let labels = if s.input == 0 { &a.labels } else { &b.labels };
        assert_eq!(labels[s.bone.index()], "left_upper_arm");
    }
}

#[test]
fn per_bone_options_and_threshold() {
    let src = entry("mixamo");
    let tgt = entry("long_tailed");
    let mut opts = MapOptions::default();
    opts.bone_options.insert(
        "Head".into(),
        BoneOptions {
            delay_secs: 0.25,
            reverse: true,
            weight: 0.5,
        },
    );
    let table = map_at_rest(&src.skeleton, &tgt.skeleton, &opts);
    let head = table.get(tgt.skeleton.bone("Head").unwrap()).unwrap();
    assert_eq!(
        head.options,
        BoneOptions {
            delay_secs: 0.25,
            reverse: true,
            weight: 0.5
        }
    );
    // The tail has no counterpart: unmapped by default, driven by the spine (similar type)
    // when the threshold is lowered.
    let tail = tgt.skeleton.bone("Tail01").unwrap();
    assert!(table.get(tail).is_none());
    let low = MapOptions {
        threshold: 30.0,
        remove_duplicates: false,
        ..MapOptions::default()
    };
    let table = map_at_rest(&src.skeleton, &tgt.skeleton, &low);
    assert!(table.get(tail).is_some());
    // A threshold nobody reaches maps nothing.
    let high = MapOptions {
        threshold: 1e6,
        ..MapOptions::default()
    };
    let table = map_at_rest(&src.skeleton, &tgt.skeleton, &high);
    assert_eq!(table.num_mapped(), 0);
}

#[test]
fn mapping_file_round_trip_and_overrides() {
    let src = entry("cmu_cgspeed");
    let tgt = entry("mixamo");
    let (ss, ts) = (&src.skeleton, &tgt.skeleton);
    let table = map_at_rest(ss, ts, &MapOptions::default());
    let text = file::mapping_file_to_string(&to_mapping_file(&table, &[ss], ts));
    let parsed = parse_mapping_file(&text).unwrap();
    let mut rebuilt = MappingTable::empty(ts.num_bones());
    apply_overrides(&mut rebuilt, &parsed, &[ss], ts).unwrap();
    for t in ts.bone_ids() {
        assert_eq!(
            rebuilt.get(t).map(|e| e.sources.clone()),
            table.get(t).map(|e| e.sources.clone()),
            "{}",
            ts.name(t)
        );
    }
    // A partial override: one bone re-pointed with options, one cleared.
    let partial = r#"
version = 1
[bones."mixamorig:LeftArm"]
source = "LeftForeArm"
delay_secs = 0.1
reverse = true
[bones."mixamorig:Head"]
unmapped = true
"#;
    let o = parse_mapping_file(partial).unwrap();
    let mut merged = table.clone();
    apply_overrides(&mut merged, &o, &[ss], ts).unwrap();
    let la = merged.get(ts.bone("mixamorig:LeftArm").unwrap()).unwrap();
    assert_eq!(la.primary().unwrap().bone, ss.bone("LeftForeArm").unwrap());
    assert!(la.options.reverse);
    assert_eq!(la.options.delay_secs, 0.1);
    assert!(merged.get(ts.bone("mixamorig:Head").unwrap()).is_none());
    let spine = ts.bone("mixamorig:Spine").unwrap();
    assert_eq!(merged.get(spine), table.get(spine));

    // Errors name what is wrong and change nothing.
    let bad_target = parse_mapping_file("version = 1\n[bones.Nope]\nsource = \"Hips\"\n").unwrap();
    let mut untouched = table.clone();
    let err = apply_overrides(&mut untouched, &bad_target, &[ss], ts).unwrap_err();
    assert_eq!(
        err,
        MappingFileError::UnknownTargetBone {
            name: "Nope".into()
        }
    );
    assert_eq!(untouched, table);
    let bad_source =
        parse_mapping_file("version = 1\n[bones.\"mixamorig:Hips\"]\nsource = \"Pelvis9\"\n")
            .unwrap();
    let err = apply_overrides(&mut untouched, &bad_source, &[ss], ts).unwrap_err();
    assert!(err.to_string().contains("Pelvis9"), "{err}");
    let err = parse_mapping_file("version = 1\n[bones.x\nsource = 3\n").unwrap_err();
    assert!(err.to_string().contains("line 2"), "{err}");
    assert!(matches!(
        parse_mapping_file("version = 7\n"),
        Err(MappingFileError::Version { found: 7, .. })
    ));
}

#[test]
fn cache_keys_invalidate_on_skeleton_or_option_change() {
    let src = entry("mixamo");
    let tgt = entry("horse");
    let opts = MapOptions::default();
    let key = CacheKey::new(&[&src.skeleton], &tgt.skeleton, &opts);
    assert_eq!(
        key,
        CacheKey::new(&[&src.skeleton], &tgt.skeleton, &MapOptions::default())
    );
    let mirrored = MapOptions {
        mirror: true,
        ..MapOptions::default()
    };
    assert_ne!(
        key,
        CacheKey::new(&[&src.skeleton], &tgt.skeleton, &mirrored)
    );
    let moved = rotate_root(&tgt.skeleton, Quat::from_rotation_y(0.3));
    assert_ne!(key, CacheKey::new(&[&src.skeleton], &moved, &opts));
    assert_ne!(
        key.file_stem(),
        CacheKey::new(&[&src.skeleton], &moved, &opts).file_stem()
    );

    let table = map_at_rest(&src.skeleton, &tgt.skeleton, &opts);
    let text = cache::encode(&key, &table);
    assert_eq!(cache::decode(&text, &key), Some(table.clone()));
    let other = CacheKey::new(&[&src.skeleton], &moved, &opts);
    assert_eq!(cache::decode(&text, &other), None);
    assert_eq!(cache::decode("{not json", &key), None);

    let mut mem = MappingCache::new();
    let mut computed = 0;
    for _ in 0..3 {
        mem.get_or_insert_with(key.clone(), || {
            computed += 1;
            table.clone()
        });
    }
    assert_eq!(computed, 1);
    assert_eq!(mem.len(), 1);
}

#[test]
fn colours_are_stable_and_follow_chains() {
    let src = entry("mixamo");
    let tgt = entry("unreal");
    let ta = analyze(&SkeletonView::rest(&tgt.skeleton));
    let table = map_at_rest(&src.skeleton, &tgt.skeleton, &MapOptions::default());
    let c1 = mapping_colors(&tgt.skeleton, &ta, &table);
    let c2 = mapping_colors(&tgt.skeleton, &ta, &table);
    assert_eq!(c1, c2);
    for (t, c) in tgt.skeleton.bone_ids().zip(&c1) {
        assert_eq!(c.is_some(), table.get(t).is_some());
        if let Some(c) = c {
            assert!(c
                .gradient
                .iter()
                .chain(&c.random)
                .all(|v| (0.0..=1.0).contains(v)));
        }
    }
    // Along the arm the gradient brightens (value = max channel grows with position).
    let up = tgt.skeleton.bone("upperarm_l").unwrap();
    let lo = tgt.skeleton.bone("lowerarm_l").unwrap();
    let v = |b: rigcast_retarget::BoneId| {
        c1[b.index()]
            .unwrap()
            .gradient
            .iter()
            .cloned()
            .fold(0.0, f32::max)
    };
    assert!(v(lo) > v(up));
    // Random colours differ between neighbours.
    assert_ne!(
        c1[up.index()].unwrap().random,
        c1[lo.index()].unwrap().random
    );
}

#[test]
fn humanoid_roles_use_unity_names_and_accept_ground_truth() {
    let e = entry("mixamo_anon");
    let a = analyze(&SkeletonView::rest(&e.skeleton));
    assert!(a.humanoid);
    let roles = humanoid_roles(&e.skeleton, &a, None);
    let find = |h: HumanBone| {
        roles
            .iter()
            .find(|(x, _)| *x == h)
            .map(|(_, b)| e.labels[b.index()].clone())
    };
    assert_eq!(
        find(HumanBone::LeftUpperArm).as_deref(),
        Some("left_upper_arm")
    );
    assert_eq!(
        find(HumanBone::RightLowerLeg).as_deref(),
        Some("right_lower_leg")
    );
    assert_eq!(find(HumanBone::Hips).as_deref(), Some("hips"));
    assert_eq!(find(HumanBone::UpperChest).as_deref(), Some("chest"));
    assert_eq!(
        find(HumanBone::LeftIndexProximal).as_deref(),
        Some("left_index_1")
    );
    assert_eq!(HumanBone::LeftUpperArm.unity_name(), "LeftUpperArm");
    assert_eq!(
        HumanBone::parse("leftUpperArm"),
        Some(HumanBone::LeftUpperArm)
    );
    // Ground truth wins.
    let truth = vec![(
        "leftUpperArm".to_string(),
        e.skeleton.name(rigcast_retarget::BoneId(0)).to_string(),
    )];
    let roles = humanoid_roles(&e.skeleton, &a, Some(&truth));
    let lua = roles
        .iter()
        .find(|(h, _)| *h == HumanBone::LeftUpperArm)
        .unwrap();
    assert_eq!(lua.1, rigcast_retarget::BoneId(0));
    // A quadruped is not humanoid.
    let horse = entry("horse");
    let ha = analyze(&SkeletonView::rest(&horse.skeleton));
    assert!(!ha.humanoid);
    assert!(humanoid_roles(&horse.skeleton, &ha, None).is_empty());
}

#[test]
fn corpus_has_every_kind_and_variant() {
    let all = corpus::all();
    assert!(all.len() >= 12 * 3 - 1);
    for e in &all {
        assert_eq!(e.labels.len(), e.skeleton.num_bones(), "{}", e.name);
        assert!(e.labels.iter().all(|l| !l.is_empty()), "{}", e.name);
    }
    let anon = all.iter().find(|e| e.name == "mixamo_anon").unwrap();
    assert!(anon.skeleton.names().iter().all(|n| n.starts_with('j')));
    assert_eq!(corpus::humanoid_65().unwrap().skeleton.num_bones(), 65);
    assert_eq!(corpus::creature_187().unwrap().skeleton.num_bones(), 187);
    // A-pose: the left hand is ~45° below the shoulder.
    let a = all.iter().find(|e| e.name == "mixamo_apose").unwrap();
    let w = rigcast_retarget::world_transforms(&a.skeleton, &a.skeleton.rest_pose());
    let sh = a.skeleton.bone("mixamorig:LeftArm").unwrap();
    let hand = a.skeleton.bone("mixamorig:LeftHand").unwrap();
    let d = w[hand.index()].translation - w[sh.index()].translation;
    let ang = (-d.y).atan2(d.x).to_degrees();
    assert!((ang - 45.0).abs() < 2.0, "{ang}");
}

/// A plain chain of bones (a tentacle, a rope, a test rig) is a body of its own: mapped onto a
/// copy of itself, every bone maps to itself (no bone is taken for an armature node above it).
#[test]
fn a_plain_chain_maps_onto_itself() {
    let mut raw = RawSkeleton::default();
    let mut parent = None;
    for i in 0..6 {
        let offset = if i == 0 {
            Vec3::ZERO
        } else {
            Vec3::new(0.0, 0.2, 0.01 * i as f32)
        };
        parent = Some(raw.add(
            format!("b{i}"),
            parent,
            rigcast_retarget::Transform::from_translation(offset),
        ));
    }
    let chain = Skeleton::build(&raw).unwrap();
    let table = map_at_rest(&chain, &chain, &MapOptions::default());
    for b in chain.bone_ids() {
        let e = table.entries[b.index()].as_ref();
        assert_eq!(e.map(|e| e.sources[0].bone), Some(b), "{}", chain.name(b));
    }
}

/// A helper above the hips (an armature root the body hangs from) carries the whole body: it
/// maps onto a helper above the other rig's hips, never onto a helper elsewhere (an end joint
/// at the head read as one). Driven by such a leaf, the target's root followed the source's head:
/// LaFAN1's walk onto three glTF characters whose body hangs from a root at the ground, their
/// feet 0.4-1 m under it.
#[test]
fn a_root_above_the_hips_is_not_driven_by_a_helper_elsewhere() {
    use rigcast_retarget::analysis::Role;
    use rigcast_retarget::Transform;
    let base = entry("mixamo");
    // The target: the same body hung from a root at the ground.
    let mut raw = RawSkeleton::default();
    let root = raw.add("Root", None, Transform::IDENTITY);
    for b in base.skeleton.to_raw().bones {
        raw.add(b.name, Some(b.parent.map_or(root, |p| p + 1)), b.rest);
    }
    let target = Skeleton::build(&raw).unwrap();
    // The source: the body with an end joint at its head's (zero length, as LaFAN1's).
    let mut raw = base.skeleton.to_raw();
    let head = base.labels.iter().position(|l| l == "head").unwrap();
    raw.add("Head_end", Some(head), Transform::IDENTITY);
    let source = Skeleton::build(&raw).unwrap();
    let role = |s: &Skeleton, name: &str| {
        let a = analyze(&SkeletonView::rest(s));
        a.roles[s.bone(name).unwrap().index()].role
    };
    assert_eq!(role(&target, "Root"), Role::Helper);
    assert_eq!(role(&source, "Head_end"), Role::Helper);
    let table = map_at_rest(&source, &target, &MapOptions::default());
    let driver = |t: &str| {
        let e = table.entries[target.bone(t).unwrap().index()].as_ref();
        e.and_then(|e| e.primary())
            .map(|s| source.name(s.bone).to_string())
    };
    assert_eq!(
        driver("Root"),
        None,
        "the root follows a bone that is not above the hips"
    );
    let hips = base.labels.iter().position(|l| l == "hips").unwrap();
    let hips = base.skeleton.name(rigcast_retarget::BoneId(hips as u16));
    assert_eq!(driver(hips).as_deref(), Some(hips));
}

/// A helper in a body section maps only onto a helper in a section of the same kind: an end
/// joint at a toe never drives one at a hand (LaFAN1's zero-length toe ends drove a finger of
/// RobotExpressive, and the retarget took that finger for a foot: its legs' ratio 2.88
/// against 1.79).
#[test]
fn a_toe_end_does_not_drive_a_hand_end() {
    use rigcast_retarget::analysis::Role;
    use rigcast_retarget::Transform;
    let base = entry("mixamo");
    // A zero-length end joint (as LaFAN1's) at the bone labelled `label`.
    let with_end = |label: &str, name: &str| {
        let mut raw = base.skeleton.to_raw();
        let at = base.labels.iter().position(|l| l == label).unwrap();
        raw.add(name, Some(at), Transform::IDENTITY);
        Skeleton::build(&raw).unwrap()
    };
    let source = with_end("left_toes", "LeftToe_end");
    let target = with_end("left_hand", "LeftFinger_end");
    let role = |s: &Skeleton, name: &str| {
        let a = analyze(&SkeletonView::rest(s));
        a.roles[s.bone(name).unwrap().index()].role
    };
    assert_eq!(role(&source, "LeftToe_end"), Role::Helper);
    assert_eq!(role(&target, "LeftFinger_end"), Role::Helper);
    let table = map_at_rest(&source, &target, &MapOptions::default());
    let e = table.entries[target.bone("LeftFinger_end").unwrap().index()].as_ref();
    let driver = e
        .and_then(|e| e.primary())
        .map(|s| source.name(s.bone).to_string());
    assert_ne!(driver.as_deref(), Some("LeftToe_end"));
}
