//! `VisionSource` as a live source: a video served through the pipeline yields BlazePose
//! poses with health, sequence numbers and raw landmark records.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::time::Duration;

use common::assets_or_skip;
use rigcast_retarget::approx::quat_angle;
use rigcast_sources::live::{LiveSource, MemoryTap, RawKind, SourceState};
use rigcast_sources::vision::source::decode_landmarks;
use rigcast_sources::vision::{FfmpegSource, PipelineConfig, PosePipeline, VisionSource};

#[test]
fn video_served_as_live_source_moves_the_blazepose_skeleton() {
    let Some(assets) = assets_or_skip("vision live source") else {
        return;
    };
    let frames = FfmpegSource::open(&assets.pose2sim_video(4)).unwrap();
    let config = PipelineConfig {
        assets: assets.clone(),
        ..PipelineConfig::default()
    };
    let pipeline = PosePipeline::new(&config).unwrap();
    let mut source = VisionSource::new("video:cam04", Box::new(frames), pipeline, false);
    let tap = MemoryTap::default();
    source.set_raw_tap(Some(Box::new(tap.clone())));
    let skeleton = source.skeleton().unwrap();
    assert_eq!(skeleton.num_bones(), 19);
    assert_eq!(source.status().state, SourceState::Connecting);

    let mut pose = skeleton.rest_pose();
    let mut metas = Vec::new();
    let mut left_knee_angles = Vec::new();
    let knee = skeleton.bone("leftLowerLeg").unwrap();
    for _ in 0..200 {
        match source
            .next_frame(Duration::from_millis(100), &mut pose)
            .unwrap()
        {
            Some(meta) => {
                metas.push(meta);
                left_knee_angles.push(quat_angle(pose.rotation(knee), glam::Quat::IDENTITY));
                assert!(pose
                    .rotations
                    .iter()
                    .all(|q| q.is_finite() && q.is_normalized()));
            }
            None if source.status().state == SourceState::Lost => break,
            None => {}
        }
    }
    assert!(metas.len() >= 95, "only {} frames", metas.len());
    assert!(metas[0].skeleton_changed && !metas[1].skeleton_changed);
    assert!(metas.windows(2).all(|w| w[1].seq == w[0].seq + 1));
    // End of the file: the source reports itself lost.
    assert_eq!(source.status().state, SourceState::Lost);
    // The performer moves: the knee is not frozen at one angle.
    let (lo, hi) = left_knee_angles
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), &a| (lo.min(a), hi.max(a)));
    assert!(hi - lo > 0.1, "knee angle range {lo}..{hi}");

    // One landmark record per processed frame: the raw landmarks for frames with a person,
    // an empty "no person" record for the others; times follow the video's 1/fps steps.
    let packets = tap.packets.lock().unwrap();
    assert!(packets.iter().all(|p| p.kind == RawKind::Landmarks));
    let with_person = packets.iter().filter(|p| !p.bytes.is_empty()).count();
    assert_eq!(with_person, metas.len());
    assert_eq!(packets.len(), 100, "cam04 has 100 frames");
    let lm = decode_landmarks(&packets[0].bytes).unwrap();
    assert!(lm.presence > 0.5);
    let step = (packets[1].capture_nanos - packets[0].capture_nanos) as f64 * 1e-9;
    assert!((step - 1.0 / 60.0).abs() < 1e-6, "tap time step {step}");
}
