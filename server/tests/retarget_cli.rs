//! `rigcast retarget` as a user runs it: the real binary on real files. A target whose
//! geometry cannot be read as the body its names describe (such as the Kinect export in the
//! shared data: offsets shifted one level, its "ankle" at the knee) is retargeted by its names
//! and the command says so on stderr; an ordinary target prints no warning. The targets are
//! the labelled human clips, told apart by their labelled legs' own lengths (not by the
//! analysis under test). Skips with a printed reason when the shared data is absent.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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

/// Whether the labelled legs of `l` (loaded as `clip`) have a body's proportions at rest: on
/// each side the thigh (labelled upper leg to lower leg) and the shin (lower leg to foot) are
/// within a factor of three of each other (a person's are about equal). A rig whose offsets
/// are shifted a level, its knee beside its hip, fails.
fn legs_have_lengths(l: &common::Labelled, clip: &rigcast_retarget::Clip) -> bool {
    let rest = rigcast_retarget::world_transforms(&clip.skeleton, &clip.skeleton.rest_pose());
    let at = |role: &str| Some(rest[clip.skeleton.bone(l.bone(role)?)?.index()].translation);
    ["L", "R"].iter().all(|side| {
        let [hip, knee, foot] =
            ["upperLeg", "lowerLeg", "foot"].map(|r| at(&format!("{r}.{side}")));
        let (Some(hip), Some(knee), Some(foot)) = (hip, knee, foot) else {
            return false;
        };
        let (thigh, shin) = (hip.distance(knee), knee.distance(foot));
        thigh > 0.0 && shin > 0.0 && thigh <= 3.0 * shin && shin <= 3.0 * thigh
    })
}

/// The first labelled walk (found by its motion) onto every labelled human clip with legs
/// (each a `rigcast retarget` of the walk): a target whose labelled legs have no lengths is
/// announced as read by its names and still gets its whole skeleton, every frame of the walk;
/// every other target prints no warning.
#[test]
fn a_target_read_by_its_names_is_announced_and_an_ordinary_one_is_not() {
    let Some((walk, walk_clip, _)) = common::first_walk() else {
        return;
    };
    let targets = common::labelled_where("human clip with legs", |l| {
        l.kind() == "human" && l.has_legs() && l.is_bvh() && l.rel != walk.rel
    });
    let (mut odd, mut ordinary) = (0, 0);
    for t in targets {
        let target = rigcast_sources::load_clip(&t.path).unwrap();
        let out = tmp(&format!("onto_{}.bvh", t.rel.replace('/', "_")));
        let run = retarget(&walk.path, &t.path, &out);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{}: {stderr}", t.rel);
        if legs_have_lengths(&t, &target) {
            println!("{}: an ordinary target", t.rel);
            assert!(!stderr.contains("warning"), "{}: {stderr}", t.rel);
            ordinary += 1;
            continue;
        }
        println!("{}: legs without lengths", t.rel);
        odd += 1;
        assert!(
            stderr.contains("warning: target: the geometry does not read as the body its names"),
            "{}: {stderr}",
            t.rel
        );
        assert!(!stderr.contains("warning: source"), "{stderr}");
        // The output still holds the target's whole skeleton, every frame of the walk.
        let written = rigcast_sources::load_clip(&out).unwrap();
        assert_eq!(written.skeleton.names(), target.skeleton.names());
        assert_eq!(written.num_frames(), walk_clip.num_frames());
    }
    println!("{odd} targets read by their names, {ordinary} ordinary");
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
