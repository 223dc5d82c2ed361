//! End-to-end test of the real `rigcast pose` binary on 20 frames of the pose2sim demo
//! footage (cam01, 1080×1920, 60 fps): `--json` prints exactly one JSON object with the
//! documented shape, image landmarks lie inside the input's pixels, and `-o` writes a BVH that
//! loads back on the BlazePose skeleton with one frame per video frame.
//!
//! Needs the vision setup (`scripts/setup-vision.sh`, i.e. `rigcast setup vision`); without it
//! the test fails with that command, unless `RIGCAST_SKIP_VISION=1`.
#![allow(clippy::unwrap_used)] // tests may unwrap

use std::path::PathBuf;
use std::process::{Command, Output};

use rigcast_sources::vision::blazepose_skeleton;

const FRAMES: usize = 20;
const WIDTH: f64 = 1080.0;
const HEIGHT: f64 = 1920.0;

#[path = "../../sources/tests/vision_common.rs"]
mod vision_common;
use vision_common::assets_or_skip;

fn rigcast(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args(args)
        .output()
        .unwrap()
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("rigcast-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn numbers(v: &serde_json::Value, len: usize, what: &str) -> Vec<f64> {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("{what}: not an array: {v}"));
    assert_eq!(a.len(), len, "{what}: {v}");
    a.iter()
        .map(|x| {
            x.as_f64()
                .unwrap_or_else(|| panic!("{what}: not a number: {x}"))
        })
        .collect()
}

#[test]
fn pose_json_and_bvh_on_real_footage() {
    let Some(assets) = assets_or_skip("rigcast pose") else {
        return;
    };
    let video = assets.pose2sim_video(1);
    let tmp = TempDir::new("pose-cli");
    let bvh = tmp.0.join("out.bvh");
    let max = FRAMES.to_string();
    let out = rigcast(&[
        "pose",
        video.to_str().unwrap(),
        "--json",
        "-o",
        bvh.to_str().unwrap(),
        "--max-frames",
        &max,
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "rigcast pose failed: {stderr}");
    // Progress goes to standard error, never into the JSON.
    assert!(stderr.contains("pose: 20 frames"), "{stderr}");
    // The summary tells how long the first pose took, within the run's own time.
    let summary = stderr
        .lines()
        .find(|l| l.starts_with("pose: 20 frames"))
        .unwrap();
    let number_after = |key: &str| -> f64 {
        let rest = &summary[summary.find(key).unwrap_or_else(|| panic!("{summary}")) + key.len()..];
        let end = rest
            .find(|c: char| !c.is_ascii_digit() && c != '.')
            .unwrap();
        rest[..end].parse().unwrap()
    };
    let first_ms = number_after("first pose after ");
    let before_secs = &summary[..summary.find(" s (").unwrap()];
    let total_ms: f64 = before_secs
        .rsplit(' ')
        .next()
        .unwrap()
        .parse::<f64>()
        .unwrap()
        * 1e3;
    assert!(first_ms > 0.0 && first_ms <= total_ms + 50.0, "{summary}");

    // Exactly one JSON object on standard output.
    let stdout = String::from_utf8(out.stdout).unwrap();
    let mut stream = serde_json::Deserializer::from_str(&stdout).into_iter::<serde_json::Value>();
    let doc = stream.next().unwrap().unwrap();
    assert!(
        stream.next().is_none(),
        "more than one JSON value on stdout"
    );
    let obj = doc.as_object().unwrap();
    assert_eq!(obj.len(), 2, "keys: {:?}", obj.keys().collect::<Vec<_>>());
    assert_eq!(doc["fps"].as_f64().unwrap(), 60.0);
    let frames = doc["frames"].as_array().unwrap();
    assert_eq!(frames.len(), FRAMES);

    let mut with_person = 0;
    for (i, f) in frames.iter().enumerate() {
        assert_eq!(f.as_object().unwrap().len(), 4, "frame {i}: {f}");
        // One entry per identity slot (two by default); slot #0 is the top-level person.
        let people = f["people"].as_array().unwrap();
        assert_eq!(people.len(), 2, "frame {i}: {f}");
        assert_eq!(people[0]["image"], f["image"], "frame {i}");
        assert_eq!(people[0]["world"], f["world"], "frame {i}");
        let t = f["time_secs"].as_f64().unwrap();
        assert!((t - i as f64 / 60.0).abs() < 1e-4, "frame {i}: time {t}");
        match (&f["image"], &f["world"]) {
            (serde_json::Value::Null, serde_json::Value::Null) => {}
            (image, world) => {
                with_person += 1;
                assert_eq!(image.as_array().unwrap().len(), 33);
                assert_eq!(world.as_array().unwrap().len(), 33);
                for (k, p) in image.as_array().unwrap().iter().enumerate() {
                    let p = numbers(p, 4, &format!("frame {i} image {k}"));
                    assert!(
                        (0.0..=WIDTH).contains(&p[0]) && (0.0..=HEIGHT).contains(&p[1]),
                        "frame {i} landmark {k} outside the {WIDTH}x{HEIGHT} input: {p:?}"
                    );
                    assert!((0.0..=1.0).contains(&p[3]), "visibility {p:?}");
                }
                for (k, p) in world.as_array().unwrap().iter().enumerate() {
                    let p = numbers(p, 3, &format!("frame {i} world {k}"));
                    // Hip-centred metres: a person fits in ±1.5 m.
                    assert!(
                        p.iter().all(|c| c.abs() < 1.5),
                        "frame {i} world {k}: {p:?}"
                    );
                }
                // The performer stands upright in this clip: nose above the ankles in the
                // image (y down) and in the world (y down too).
                let y = |v: &serde_json::Value, k: usize| v[k][1].as_f64().unwrap();
                assert!(y(image, 0) < y(image, 27) && y(image, 0) < y(image, 28));
                assert!(y(world, 0) < y(world, 27) && y(world, 0) < y(world, 28));
            }
        }
    }
    assert!(
        with_person >= 19,
        "person in only {with_person} of {FRAMES} frames"
    );

    // The BVH: BlazePose skeleton, one frame per video frame, at the video's rate.
    let clip = rigcast_sources::load_clip(&bvh).unwrap();
    let blazepose = blazepose_skeleton().unwrap();
    assert_eq!(clip.skeleton.names(), blazepose.names());
    assert_eq!(clip.skeleton.parents(), blazepose.parents());
    for b in blazepose.bone_ids() {
        let (got, want) = (
            clip.skeleton.rest()[b.index()].translation,
            blazepose.rest()[b.index()].translation,
        );
        assert!(
            (got - want).length() < 1e-3,
            "{}: {got} vs {want}",
            blazepose.name(b)
        );
    }
    assert_eq!(clip.poses.len(), FRAMES);
    assert!((clip.frame_time_secs - 1.0 / 60.0).abs() < 1e-5);
    // It is motion, not the rest pose repeated.
    let moved = clip.poses.iter().any(|p| {
        p.rotations
            .iter()
            .any(|q| q.angle_between(glam::Quat::IDENTITY) > 0.2)
    });
    assert!(moved, "every BVH frame is at rest");
}

#[test]
fn missing_video_fails_naming_the_file() {
    let tmp = TempDir::new("pose-missing");
    let video = tmp.0.join("no-such-video.mp4");
    let out = rigcast(&["pose", video.to_str().unwrap(), "--json"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no-such-video.mp4"), "{stderr}");
    assert!(
        out.stdout.is_empty(),
        "stdout: {}",
        String::from_utf8_lossy(&out.stdout)
    );
}

#[test]
fn nothing_to_do_is_an_error() {
    let out = rigcast(&["pose", "whatever.mp4"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--json") && stderr.contains("-o"),
        "{stderr}"
    );
}
