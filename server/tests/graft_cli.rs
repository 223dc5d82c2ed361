//! `rigcast graft` as a user runs it: the real binary on real files (the summary on stdout,
//! the progress bar on stderr, the output on the lower clip's rig and frame count), and bad
//! input (a missing file, an unwritable format, a one-frame clip, a rig whose legs the analysis does not find) as a
//! short error and a failing exit status, never a panic. Real-data cases skip with a printed
//! reason when the shared data is absent.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Arc;

use rigcast_retarget::{Clip, RawSkeleton, Skeleton, Transform};

fn graft(upper: &Path, lower: &Path, out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args(["graft", "--upper"])
        .arg(upper)
        .arg("--lower")
        .arg(lower)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rigcast-graft-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The second labelled walk's upper body on the first (both found by their motion).
#[test]
fn graft_writes_the_lower_rig_and_prints_a_summary() {
    let walks = common::first_walks(2);
    let [Some(low), Some(up)] = [walks.first(), walks.get(1)].map(|w| w.map(|w| w.0.path.clone()))
    else {
        println!("SKIP: fewer than two labelled walks");
        return;
    };
    let out = tmp("grafted.bvh");
    let o = graft(&up, &low, &out);
    let (stdout, stderr) = (text(&o.stdout), text(&o.stderr));
    assert!(o.status.success(), "{stdout}\n{stderr}");
    println!("{stdout}");
    assert!(
        stderr.contains("grafting [") && stderr.contains("100%"),
        "{stderr}"
    );
    for needle in [
        "landings in the upper clip",
        "paired",
        "plays at",
        "clusters shared",
    ] {
        assert!(stdout.contains(needle), "no '{needle}' in {stdout}");
    }
    let (grafted, walk) = (
        rigcast_sources::load_clip(&out).unwrap(),
        rigcast_sources::load_clip(&low).unwrap(),
    );
    assert_eq!(grafted.skeleton.names(), walk.skeleton.names());
    assert_eq!(grafted.num_frames(), walk.num_frames());
}

#[test]
fn bad_input_is_a_short_error() {
    let walk = common::first_walk().map(|w| w.0.path);
    // Known answer: RobotExpressive's legs are ones the analysis does not find (read by hand;
    // no label says so). The case is left out without the file.
    let robot = common::shared_data("zoo/gltf/robotexpressive__RobotExpressive.glb");
    // A one-frame clip, written here (no shared data needed).
    let still = tmp("still.bvh");
    let mut raw = RawSkeleton::default();
    let root = raw.add("root", None, Transform::IDENTITY);
    raw.add(
        "tip",
        Some(root),
        Transform::from_translation(glam::Vec3::Y),
    );
    let skel = Arc::new(Skeleton::build(&raw).unwrap());
    let clip = Clip::new("still", skel.clone(), vec![skel.rest_pose()], 1.0 / 30.0).unwrap();
    rigcast_sources::save_clip(&still, &clip).unwrap();
    let mut cases: Vec<(PathBuf, PathBuf, PathBuf, &str)> = vec![
        (
            tmp("missing.bvh"),
            still.clone(),
            tmp("o.bvh"),
            "cannot read the upper clip",
        ),
        (
            still.clone(),
            still.clone(),
            tmp("o.fbx"),
            "cannot write .fbx",
        ),
        (
            still.clone(),
            still.clone(),
            tmp("o.bvh"),
            "no motion to graft",
        ),
    ];
    if let (Some(walk), Some(robot)) = (walk, robot) {
        cases.push((
            walk,
            robot,
            tmp("o.glb"),
            "cannot cut the body at the waist",
        ));
    }
    for (upper, lower, out, want) in cases {
        let o = graft(&upper, &lower, &out);
        let stderr = text(&o.stderr);
        assert!(!o.status.success(), "{upper:?} {lower:?} {out:?} succeeded");
        assert!(stderr.contains(want), "expected '{want}' in {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(stderr.lines().count() <= 3, "{stderr}");
    }
}
