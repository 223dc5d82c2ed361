//! Acceptance (issue 4): retargeting onto a copy of the same skeleton built differently —
//! renamed bones, shuffled child order, different bone local axes (glTF-style rest rotations),
//! different units, a different facing — reproduces the world joint positions within
//! 1e-4 × height on every frame.

mod retarget_fixtures;

use retarget_fixtures::{motion, positions, rest_height, table_by_canonical, Axes, Humanoid};
use rigcast_retarget::{Mapping, RetargetOptions};

fn check_identity(name: &str, target_spec: Humanoid) {
    let source_spec = Humanoid::default();
    let source = source_spec.build();
    let target = target_spec.build();
    let table = table_by_canonical(&source, source_spec.prefix, &target, target_spec.prefix);
    assert_eq!(
        table.num_mapped(),
        target.num_bones(),
        "{name}: every bone mapped"
    );
    let mut mapping =
        Mapping::build(&[&source], &target, &table, &RetargetOptions::default()).expect("build");
    let scale = mapping.root_scale().expect("root");
    assert!(
        (scale - target_spec.units).abs() < 1e-4 * target_spec.units,
        "{name}: root scale {scale}"
    );
    let height = rest_height(&source);
    let tol = 1e-4 * height;
    let frames = motion(&source, 120, 0.0, 1.0);
    let mut out = mapping.new_target_pose();
    let mut worst = 0.0f32;
    for (f, pose) in frames.iter().enumerate() {
        mapping.apply_one(pose, &mut out).expect("apply");
        let ps = positions(&source, pose);
        let pt = positions(&target, &out);
        for t in target.bone_ids() {
            let canon = target_spec.canonical(target.name(t));
            let s = source.bone(canon).expect("same bones");
            let err = (pt[t.index()] / target_spec.units - ps[s.index()]).length();
            worst = worst.max(err);
            assert!(
                err <= tol,
                "{name}: frame {f} bone {canon}: error {err} m > {tol} m"
            );
        }
    }
    println!("{name}: worst joint error {worst:.2e} m (tolerance {tol:.2e} m)");
}

#[test]
fn identity_renamed() {
    check_identity(
        "renamed",
        Humanoid {
            prefix: "mixamorig:",
            ..Humanoid::default()
        },
    );
}

#[test]
fn identity_shuffled_children() {
    let spec = Humanoid {
        shuffle: true,
        ..Humanoid::default()
    };
    // The shuffle must really change the bone order, or this test proves nothing.
    assert_ne!(spec.build().names(), Humanoid::default().build().names());
    check_identity("shuffled", spec);
}

#[test]
fn identity_gltf_bone_axes() {
    check_identity(
        "bone axes",
        Humanoid {
            axes: Axes::AlongBone { roll_rad: 0.7 },
            ..Humanoid::default()
        },
    );
}

#[test]
fn identity_centimetres() {
    check_identity(
        "units",
        Humanoid {
            units: 100.0,
            ..Humanoid::default()
        },
    );
}

#[test]
fn identity_facing_the_other_way() {
    // The copy faces -Z at rest; alignment turns it to face where the source faces.
    check_identity(
        "facing",
        Humanoid {
            yaw_rad: std::f32::consts::PI * 0.75,
            ..Humanoid::default()
        },
    );
}

#[test]
fn identity_everything_at_once() {
    check_identity(
        "all",
        Humanoid {
            prefix: "DEF-",
            shuffle: true,
            axes: Axes::AlongBone { roll_rad: -1.3 },
            units: 100.0,
            yaw_rad: 0.4,
            ..Humanoid::default()
        },
    );
}
