//! Tests against the shared real data set (skipped with a message when it is absent). The
//! general tests run on every BVH and glTF file found by listing the data's folders (each is
//! cheap: a read and a write), judged against what the file's own text says (its frame count,
//! frame time and joints; its animations' names and lengths); the tests named after one file
//! check figures read by hand from it (known answers) and skip with a printed reason when it
//! is absent.
#![allow(clippy::unwrap_used)]

use rigcast_retarget::approx::{quat_close_precise as quat_close, vec_close};
use rigcast_retarget::{world_transforms, Clip};
use rigcast_sources::bvh::{read_bvh, write_bvh, BvhReadOptions, BvhWriteOptions};

#[path = "common/shared_data.rs"]
mod shared_data;
use shared_data::{data_files, data_rel, labelled, shared_data, Labelled};

fn height_m(clip: &Clip, frame: usize) -> f32 {
    let w = world_transforms(&clip.skeleton, &clip.poses[frame]);
    let ys = w.iter().map(|t| t.translation.y);
    let max = ys.clone().fold(f32::MIN, f32::max);
    let min = ys.fold(f32::MAX, f32::min);
    max - min
}

fn assert_clips_equal(a: &Clip, b: &Clip) {
    assert_eq!(a.skeleton.names(), b.skeleton.names());
    assert_eq!(a.skeleton.parents(), b.skeleton.parents());
    for (x, y) in a.skeleton.rest().iter().zip(b.skeleton.rest()) {
        assert!(vec_close(x.translation, y.translation, 1e-6));
    }
    assert_eq!(a.num_frames(), b.num_frames());
    assert!((a.frame_time_secs - b.frame_time_secs).abs() < 1e-9);
    for (f, (pa, pb)) in a.poses.iter().zip(&b.poses).enumerate() {
        for i in 0..pa.num_bones() {
            assert!(
                quat_close(pa.rotations[i], pb.rotations[i], 1e-5),
                "frame {f} bone {i}: {:?} vs {:?}",
                pa.rotations[i],
                pb.rotations[i]
            );
            assert!(
                vec_close(pa.translations[i], pb.translations[i], 1e-6),
                "frame {f} bone {i}"
            );
        }
    }
}

fn bvh_round_trip(rel: &str, joints: usize, frames: usize, fps: f64) -> Option<Clip> {
    let path = shared_data(rel)?;
    let bytes = std::fs::read(&path).unwrap();
    let r = read_bvh(&bytes, "x", &BvhReadOptions::default()).unwrap();
    assert_eq!(r.num_joints, joints, "{rel}");
    assert_eq!(r.clip.num_frames(), frames, "{rel}");
    assert!((r.clip.fps() - fps).abs() < 0.01, "{rel}: {}", r.clip.fps());
    let h = height_m(&r.clip, 0);
    assert!(
        (1.3..2.1).contains(&h),
        "{rel}: height {h} m with scale {}",
        r.scale
    );
    let text = write_bvh(&r.clip, &BvhWriteOptions::default()).unwrap();
    let back = read_bvh(text.as_bytes(), "x", &BvhReadOptions { scale: Some(0.01) }).unwrap();
    assert_clips_equal(&r.clip, &back.clip);
    // Without a given scale the written centimetres are recognised as such.
    let guessed = read_bvh(text.as_bytes(), "x", &BvhReadOptions::default()).unwrap();
    assert_eq!(guessed.scale, 0.01);
    Some(r.clip)
}

/// What a BVH file's own text says: joints (`ROOT` and `JOINT` lines), frames and the frame
/// time from the motion header.
struct BvhHeader {
    joints: usize,
    frames: usize,
    frame_time: f64,
}

fn bvh_header(text: &str) -> BvhHeader {
    let words = |line: &str| {
        line.split_whitespace()
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    let mut h = BvhHeader {
        joints: 0,
        frames: 0,
        frame_time: 0.0,
    };
    for line in text.lines() {
        let w = words(line);
        match w.first().map(String::as_str) {
            Some("ROOT" | "JOINT") => h.joints += 1,
            Some("Frames:") => h.frames = w[1].parse().unwrap(),
            Some("Frame") if w.get(1).is_some_and(|t| t == "Time:") => {
                h.frame_time = w[2].parse().unwrap()
            }
            _ => {}
        }
    }
    h
}

/// The labelled human rigs with both legs labelled (whose height a person's range bounds).
fn labelled_humans() -> Vec<Labelled> {
    labelled()
        .into_iter()
        .filter(|l| l.kind() == "human" && l.has_legs())
        .collect()
}

/// The figure's extent on `frame` along its labelled body's up: from the middle of its
/// labelled feet to its labelled head (known from the labels, whatever axis the file calls
/// up, and independent of the analysis `rigcast info` uses).
fn labelled_height_m(l: &Labelled, clip: &Clip, frame: usize) -> f32 {
    let w = world_transforms(&clip.skeleton, &clip.poses[frame]);
    let at = |role: &str| {
        let name = l.bone(role).unwrap();
        w[clip.skeleton.bone(name).unwrap().index()].translation
    };
    let up = (at("head") - (at("foot.L") + at("foot.R")) * 0.5).normalize_or_zero();
    let along = w.iter().map(|t| t.translation.dot(up));
    let max = along.clone().fold(f32::MIN, f32::max);
    let min = along.fold(f32::MAX, f32::min);
    max - min
}

/// Every BVH of the shared data (cheap: each read, written and read again): the joints,
/// frames and frame rate its text declares are read, and the clip written and read back is
/// the same clip.
#[test]
fn every_bvh_reads_and_round_trips() {
    for path in data_files("BVH clips", &["bvh"]) {
        let rel = data_rel(&path);
        let text = std::fs::read_to_string(&path).unwrap();
        let h = bvh_header(&text);
        let r = read_bvh(text.as_bytes(), "x", &BvhReadOptions::default()).unwrap();
        println!(
            "{rel}: {} joints, {} frames at {:.2} fps, {} m per unit ({:.2} sure)",
            r.num_joints,
            h.frames,
            r.clip.fps(),
            r.scale,
            r.scale_confidence
        );
        assert_eq!(r.num_joints, h.joints, "{rel}");
        assert_eq!(r.clip.num_frames(), h.frames, "{rel}");
        assert!(
            (r.clip.frame_time_secs - h.frame_time).abs() < 1e-6,
            "{rel}"
        );
        let written = write_bvh(&r.clip, &BvhWriteOptions::default()).unwrap();
        let back = read_bvh(
            written.as_bytes(),
            "x",
            &BvhReadOptions { scale: Some(0.01) },
        );
        assert_clips_equal(&r.clip, &back.unwrap().clip);
    }
}

/// The named CMU clips' size checks ([`bvh_round_trip`], [`describe_bvh_reports_scale_and_height`])
/// on every labelled human BVH with legs: 1.3-2.1 m tall on its first frame (along its labelled
/// feet-to-head axis) and in `rigcast info` (along the axis its analysis reads, at rest or on
/// the first frame when the rest is not a posture), and written in centimetres that are read
/// back as such, surely (over 0.9: a person-sized figure in centimetres is near no other unit;
/// a file's own unit may be less sure, CMU's sitting between decimetres and inches).
#[test]
fn every_labelled_human_bvh_is_person_sized_and_written_in_centimetres() {
    let mut failures = Vec::new();
    for l in labelled_humans().iter().filter(|l| l.is_bvh()) {
        let rel = &l.rel;
        let r = read_bvh(
            &std::fs::read(&l.path).unwrap(),
            "x",
            &BvhReadOptions::default(),
        )
        .unwrap();
        let height = labelled_height_m(l, &r.clip, 0);
        let described = rigcast_sources::describe(&l.path).unwrap().height_m;
        let written = write_bvh(&r.clip, &BvhWriteOptions::default()).unwrap();
        let guessed = read_bvh(written.as_bytes(), "x", &BvhReadOptions::default()).unwrap();
        println!(
            "{rel}: {height:.2} m, described {described:.2} m, read at {} ({:.2} sure), \
             written read at {} ({:.2} sure)",
            r.scale, r.scale_confidence, guessed.scale, guessed.scale_confidence
        );
        let person = 1.3..2.1;
        let centimetres = guessed.scale == 0.01 && guessed.scale_confidence > 0.9;
        if !person.contains(&height) || !person.contains(&described) || !centimetres {
            failures.push(rel.clone());
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// `rigcast info` on every BVH of the shared data (cheap) reports what its text declares: the
/// format, frames and rate, a guessed scale, every joint by name.
#[test]
fn describe_reports_every_bvh_as_its_text_declares() {
    for path in data_files("BVH clips", &["bvh"]) {
        let rel = data_rel(&path);
        let h = bvh_header(&std::fs::read_to_string(&path).unwrap());
        let info = rigcast_sources::describe(&path).unwrap();
        assert_eq!(info.format, "BVH");
        assert_eq!(info.num_frames, h.frames, "{rel}");
        assert!(
            (info.fps.unwrap() - 1.0 / h.frame_time).abs() < 0.01,
            "{rel}"
        );
        assert!(info.bvh_scale.unwrap().1, "{rel}: the scale is guessed");
        let text = info.to_string();
        assert!(text.contains(&h.frames.to_string()), "{rel}: {text}");
        for b in info.skeleton.bone_ids() {
            assert!(text.contains(info.skeleton.name(b)), "{rel}: {text}");
        }
    }
}

/// Every glTF of the shared data (cheap: each animation read twice): joints are the
/// skeleton's bones, parents come first, each animation is selected by its name and by its
/// index and sampled at a chosen rate has as many frames as its length asks, and `rigcast
/// info` lists the same animations.
#[test]
fn every_gltf_reads_each_animation_by_name_and_index() {
    use rigcast_sources::gltf::{read_gltf, GltfReadOptions};
    for path in data_files("glTF files", &["glb", "gltf", "vrm"]) {
        let rel = data_rel(&path);
        let bytes = std::fs::read(&path).unwrap();
        let read = |animation: Option<String>, sample_fps| {
            let opts = GltfReadOptions {
                animation,
                sample_fps,
            };
            read_gltf(&bytes, path.parent(), "x", &opts).unwrap()
        };
        let r = read(None, None);
        println!(
            "{rel}: {} joints, {} animations",
            r.num_joints,
            r.animations.len()
        );
        assert_eq!(r.clip.skeleton.num_bones(), r.num_joints, "{rel}");
        for (i, p) in r.clip.skeleton.parents().iter().enumerate() {
            assert!(p.is_none_or(|p| p.index() < i), "{rel}");
        }
        for (i, a) in r.animations.iter().enumerate() {
            let by_name = read(Some(a.name.clone()), Some(24.0));
            assert_eq!(by_name.clip.name, a.name, "{rel}");
            let expect = (a.duration_secs * 24.0 + 1e-3).floor() as usize + 1;
            assert_eq!(by_name.clip.num_frames(), expect, "{rel} {}", a.name);
            assert_eq!(read(Some(i.to_string()), None).clip.name, a.name, "{rel}");
        }
        let info = rigcast_sources::describe(&path).unwrap();
        assert_eq!(info.animations.len(), r.animations.len(), "{rel}");
    }
}

/// Known answer (read by hand from this file: 31 joints, 994 frames at 120 fps): skips with a
/// printed reason without it; [`every_bvh_reads_and_round_trips`] covers every BVH.
#[test]
fn cmu_walk_reads_and_round_trips() {
    let Some(clip) = bvh_round_trip("bvh/cmu_131_01_walk.bvh", 31, 994, 120.0) else {
        return;
    };
    assert!(clip.skeleton.bone("LeftElbow").is_some());
    assert!(clip.skeleton.bone("LeftToe_end").is_some());
}

/// Known answer (31 joints, 278 frames at 120 fps, read by hand): skips without the file.
#[test]
fn cmu_31_joint_reads_and_round_trips() {
    bvh_round_trip("bvh/cmu_31joint_example.bvh", 31, 278, 120.0);
}

/// Known answer (19 joints, written in centimetres, read by hand): skips without the file.
#[test]
fn cmu_run_in_centimetres() {
    let Some(path) = shared_data("bvh/cmu_run.bvh") else {
        return;
    };
    let bytes = std::fs::read(&path).unwrap();
    let r = read_bvh(&bytes, "x", &BvhReadOptions::default()).unwrap();
    assert_eq!(r.scale, 0.01);
    assert_eq!(r.num_joints, 19);
    bvh_round_trip("bvh/cmu_run.bvh", 19, r.clip.num_frames(), r.clip.fps());
}

/// Known answer (the Fox's 24 joints and its three animations' names, read by hand): skips
/// without the file; [`every_gltf_reads_each_animation_by_name_and_index`] covers every glTF.
#[test]
fn fox_glb_skin_and_animations() {
    use rigcast_sources::gltf::{read_gltf, GltfReadOptions};
    let Some(path) = shared_data("gltf/Fox.glb") else {
        return;
    };
    let bytes = std::fs::read(&path).unwrap();
    let r = read_gltf(&bytes, path.parent(), "fox", &GltfReadOptions::default()).unwrap();
    assert_eq!(r.num_joints, 24);
    assert_eq!(r.clip.skeleton.num_bones(), 24);
    let names: Vec<&str> = r.animations.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    assert!(r.animations.iter().all(|a| a.duration_secs > 0.5));
    assert!(r.clip.skeleton.bone("b_Hip_01").is_some());
    // Parents come first (depth-first order).
    for (i, p) in r.clip.skeleton.parents().iter().enumerate() {
        assert!(p.is_none_or(|p| p.index() < i));
    }
    assert_eq!(r.clip.name, "Survey");
    assert!(r.clip.num_frames() > 10);
    // Select by name and by index, at a chosen rate.
    let opts = GltfReadOptions {
        animation: Some("Run".into()),
        sample_fps: Some(24.0),
    };
    let run = read_gltf(&bytes, path.parent(), "fox", &opts).unwrap();
    assert_eq!(run.clip.name, "Run");
    let expect = (r.animations[2].duration_secs * 24.0 + 1e-3).floor() as usize + 1;
    assert_eq!(run.clip.num_frames(), expect);
    let opts = GltfReadOptions {
        animation: Some("1".into()),
        sample_fps: None,
    };
    assert_eq!(
        read_gltf(&bytes, path.parent(), "fox", &opts)
            .unwrap()
            .clip
            .name,
        "Walk"
    );
    // The animation moves the legs: some frame differs from another.
    let p = &run.clip.poses;
    assert!(p[0] != p[p.len() / 2]);
    let info = rigcast_sources::describe(&path).unwrap();
    assert_eq!(info.animations.len(), 3);
    assert!(info.height_m > 0.1, "{}", info.height_m);
    println!("{info}");
}

/// Known answer (the glTF sample's two unnamed joints and their rest, read by hand): skips
/// without the file.
#[test]
fn simple_skin_unnamed_joints() {
    let Some(path) = shared_data("gltf/SimpleSkin.gltf") else {
        return;
    };
    let clip = rigcast_sources::load_clip(&path).unwrap();
    assert_eq!(clip.skeleton.names(), &["joint_1", "joint_2"]);
    assert!(vec_close(
        clip.skeleton.rest()[0].translation,
        glam::Vec3::new(0.0, 1.0, 0.0),
        1e-6
    ));
    assert!(clip.num_frames() > 1);
    // The second joint's rotation is animated (it bends and returns).
    let max_angle = clip
        .poses
        .iter()
        .map(|p| p.rotations[1].to_axis_angle().1.abs())
        .fold(0.0f32, f32::max);
    assert!(max_angle > 0.1, "{max_angle}");
    println!("{}", rigcast_sources::describe(&path).unwrap());
}

/// Known answer (the CMU walk's 994 frames and its guessed scale 0.056444, read by hand):
/// skips without the file; [`describe_reports_every_bvh_as_its_text_declares`] covers every
/// BVH.
#[test]
fn describe_bvh_reports_scale_and_height() {
    let Some(path) = shared_data("bvh/cmu_131_01_walk.bvh") else {
        return;
    };
    let info = rigcast_sources::describe(&path).unwrap();
    assert_eq!(info.format, "BVH");
    assert_eq!(info.num_frames, 994);
    assert!((info.fps.unwrap() - 120.0).abs() < 0.01);
    assert!((1.3..2.1).contains(&info.height_m), "{}", info.height_m);
    let (scale, guessed, _) = info.bvh_scale.unwrap();
    assert!(guessed && (scale - 0.056444).abs() < 1e-6);
    let text = info.to_string();
    assert!(text.contains("LeftElbow") && text.contains("994"));
}
