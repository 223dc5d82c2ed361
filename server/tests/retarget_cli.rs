//! `rigcast retarget` as a user runs it: the real binary on real files. A target whose
//! geometry cannot be read as the body its names describe (the Kinect export in the shared
//! data: offsets shifted one level, its "ankle" at the knee) is retargeted by its names and
//! the command says so on stderr; an ordinary target prints no warning. Skips with a printed
//! reason when the shared data is absent.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const KINECT: &str = "zoo/bvh/kinect2__test.bvh";
const XSENS: &str = "zoo/bvh/xsens__ammr_S02_Trial01.bvh";

fn retarget(anim: &Path, target: &Path, out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .arg("retarget")
        .arg(anim)
        .arg("--target")
        .arg(target)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rigcast-retarget-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn a_target_read_by_its_names_is_announced_and_an_ordinary_one_is_not() {
    let Some([walk, kinect, xsens]) = common::shared_data_all([common::CMU_WALK, KINECT, XSENS])
    else {
        return;
    };
    let out = tmp("onto_kinect.bvh");
    let run = retarget(&walk, &kinect, &out);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: target: the geometry does not read as the body its names"),
        "{stderr}"
    );
    assert!(!stderr.contains("warning: source"), "{stderr}");
    // The output still holds the target's whole skeleton, every frame of the walk.
    let written = rigcast_sources::load_clip(&out).unwrap();
    let target = rigcast_sources::load_clip(&kinect).unwrap();
    assert_eq!(written.skeleton.names(), target.skeleton.names());
    assert_eq!(
        written.num_frames(),
        rigcast_sources::load_clip(&walk).unwrap().num_frames()
    );

    let run = retarget(&walk, &xsens, &tmp("onto_xsens.bvh"));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
}

/// A target is loaded one way everywhere: `builtin:mannequin` is a character for `rigcast
/// retarget` as it is for `serve --target`, and an unknown built-in names those that exist.
#[test]
fn the_built_in_mannequin_is_a_target_as_for_serve() {
    let demo = rigcast_sources::embedded_demo().unwrap();
    let anim = tmp("demo_walk.bvh");
    rigcast_sources::save_clip(&anim, &demo).unwrap();
    let out = tmp("onto_mannequin.rcr");
    let run = retarget(&anim, Path::new("builtin:mannequin"), &out);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let written = rigcast_sources::load_clip(&out).unwrap();
    let mannequin = rigcast_engine::builtin::mannequin().unwrap();
    assert_eq!(written.skeleton.names(), mannequin.names());
    assert_eq!(written.num_frames(), demo.num_frames());

    let run = retarget(&anim, Path::new("builtin:robot"), &tmp("onto_robot.bvh"));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("unknown built-in character \"robot\"") && stderr.contains("mannequin"),
        "{stderr}"
    );
}
