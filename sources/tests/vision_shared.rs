//! [`SharedVision`]: two people of one real video (the pose2sim two-person demo, camera 2),
//! one pipeline thread, one live source each. Each person source must carry exactly its own
//! slot's poses: checked against the pipeline run offline on the same frames.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::time::Duration;

use common::assets_or_skip;
use rigcast_retarget::approx::quat_angle;
use rigcast_retarget::Pose;
use rigcast_sources::live::{LiveSource, SourceState};
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, PipelineConfig, PosePipeline, RgbFrame, SharedVision,
    VisionError,
};

/// Largest bone rotation difference between two poses, radians.
fn pose_distance(a: &Pose, b: &Pose) -> f32 {
    a.rotations
        .iter()
        .zip(&b.rotations)
        .map(|(p, q)| quat_angle(*p, *q))
        .fold(0.0, f32::max)
}

/// Every pose each slot had, running the pipeline offline over the video.
fn offline_poses(config: &PipelineConfig, video: &std::path::Path) -> Vec<Vec<Pose>> {
    let mut frames = FfmpegSource::open_at(video, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut pipeline = PosePipeline::new(config).unwrap();
    let mut frame = RgbFrame::default();
    let mut out = vec![Vec::new(), Vec::new()];
    while frames.next_frame(&mut frame).unwrap() {
        pipeline.process_frame(&frame).unwrap();
        for (slot, poses) in out.iter_mut().enumerate() {
            if pipeline.person(slot).is_some() {
                poses.push(pipeline.pose(slot).unwrap().clone());
            }
        }
    }
    out
}

/// Reads `source` until its input ends; the poses it produced.
fn drain(mut source: impl LiveSource) -> (Vec<Pose>, SourceState, String) {
    let mut pose = source.skeleton().unwrap().rest_pose();
    let mut poses = Vec::new();
    for _ in 0..2000 {
        match source
            .next_frame(Duration::from_millis(100), &mut pose)
            .unwrap()
        {
            Some(meta) => {
                assert_eq!(meta.seq, poses.len() as u64 + 1);
                poses.push(pose.clone());
            }
            None if source.status().state == SourceState::Lost => break,
            None => {}
        }
    }
    let status = source.status();
    (poses, status.state, status.detail)
}

#[test]
fn each_person_source_carries_its_own_slot_of_one_shared_pipeline() {
    let Some(assets) = assets_or_skip("shared vision") else {
        return;
    };
    let config = PipelineConfig {
        assets: assets.clone(),
        ..PipelineConfig::default()
    };
    let video = assets.pose2sim_multi_video(2);
    let expected = offline_poses(&config, &video);
    assert!(
        expected.iter().all(|p| p.len() >= 95),
        "offline: {:?}",
        expected.iter().map(Vec::len).collect::<Vec<_>>()
    );

    let frames = FfmpegSource::open_at(&video, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let shared = SharedVision::new(Box::new(frames), PosePipeline::new(&config).unwrap(), false);
    assert_eq!(shared.num_people(), 2);
    match shared.person(2, "video#2") {
        Err(e @ VisionError::NoSuchPerson { .. }) => {
            assert_eq!(
                e.to_string(),
                "person #2: only 2 people are tracked (#0..#1)"
            )
        }
        other => panic!("expected NoSuchPerson, got {other:?}"),
    }
    let sources = [
        shared.person(0, "video#0").unwrap(),
        shared.person(1, "video#1").unwrap(),
    ];
    drop(shared); // the person sources keep the pipeline alive on their own
                  // One reader thread per person, as the server runs them.
    let results: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = sources
            .into_iter()
            .map(|src| s.spawn(move || drain(src)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (slot, (poses, state, detail)) in results.iter().enumerate() {
        // Latest pose wins: a reader may skip a frame, but not many at this speed.
        assert!(poses.len() >= 90, "#{slot}: only {} frames", poses.len());
        assert_eq!(
            (*state, detail.as_str()),
            (SourceState::Lost, "end of input")
        );
        let nearest = |list: &[Pose], p: &Pose| {
            list.iter()
                .map(|q| pose_distance(p, q))
                .fold(f32::INFINITY, f32::min)
        };
        let own = poses
            .iter()
            .map(|p| nearest(&expected[slot], p))
            .fold(0.0, f32::max);
        let other_matches = poses
            .iter()
            .filter(|p| nearest(&expected[1 - slot], p) < 0.01)
            .count();
        eprintln!("#{slot}: {} frames, worst distance to own slot {own:.5} rad, {other_matches} like the other", poses.len());
        assert!(
            own < 0.01,
            "#{slot}: a pose {own} rad from every offline pose of its slot"
        );
        assert_eq!(other_matches, 0, "#{slot} carried the other person's poses");
    }
    // The two people move differently.
    let d = pose_distance(&results[0].0[40], &results[1].0[40]);
    assert!(d > 0.2, "the two subjects' poses differ by only {d} rad");
}
