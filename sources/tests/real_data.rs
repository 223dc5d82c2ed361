//! Tests against the shared real data set (skipped with a message when it is absent).
#![allow(clippy::unwrap_used)]

use rigcast_retarget::approx::{quat_close_precise as quat_close, vec_close};
use rigcast_retarget::{world_transforms, Clip};
use rigcast_sources::bvh::{read_bvh, write_bvh, BvhReadOptions, BvhWriteOptions};

#[path = "common/shared_data.rs"]
mod shared_data;
use shared_data::shared_data;

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

#[test]
fn cmu_walk_reads_and_round_trips() {
    let Some(clip) = bvh_round_trip("bvh/cmu_131_01_walk.bvh", 31, 994, 120.0) else {
        return;
    };
    assert!(clip.skeleton.bone("LeftElbow").is_some());
    assert!(clip.skeleton.bone("LeftToe_end").is_some());
}

#[test]
fn cmu_31_joint_reads_and_round_trips() {
    bvh_round_trip("bvh/cmu_31joint_example.bvh", 31, 278, 120.0);
}

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
    let (scale, guessed) = info.bvh_scale.unwrap();
    assert!(guessed && (scale - 0.056444).abs() < 1e-6);
    let text = info.to_string();
    assert!(text.contains("LeftElbow") && text.contains("994"));
}
