//! Two performers from one camera, on real footage: the pose2sim two-person demo (a woman in a
//! grey shirt in front, a shirtless man jumping behind her, a bystander at the back; 1088×1920,
//! 60 fps, four cameras), installed by `scripts/setup-vision.sh`.
//!
//! Identity is judged independently of the tracker: by the colour of each person's torso in
//! the decoded picture (grey cloth against bare skin; `common/two_person.rs`). Each identity
//! slot must keep the torso colour it started with in every frame.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/two_person.rs"]
mod two_person;

use common::assets_or_skip;
use glam::Vec2;
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, LandmarkModel, Landmarks, ModelKind, PipelineConfig,
    PosePipeline, RgbFrame,
};
use two_person::check_cameras_with;

#[test]
fn two_performers_keep_their_identities_sides_and_limb_lengths() {
    check_cameras("two-person acceptance", &[2, 4]);
}

/// The two cameras that met the acceptance bounds last, with the narrowest margins.
///
/// Camera 1: its woman's right arm, hidden behind her body for most of the clip, varied in
/// length by a cv of 0.110 until limb lengths were shared between the two sides (now 0.058).
///
/// Camera 3 films the man crossing in front of the woman with his back to the camera (frame
/// 82 on). The person detector finds faces, so there it finds only her; the landmark model run
/// on his crop puts his face on hers (the only face in it) from about frame 37 on, and from
/// frame 82 drew her body or a blend of the two: his track showed her for 3 frames until it
/// was found to duplicate hers and dropped, and nothing found him again (87 % coverage). Now a
/// result lying on another tracked person's body is not taken and crops moved away from them
/// are tried (`tracker.rs`, `ON_OTHER_BODY`): #0 (the man) is seen in 99 % of the frames, none
/// showing her. During the crossing the model reads his upper arms at 0.05–0.2 m with full
/// visibility for 40 frames; the limb-length stage no longer follows such a run (upper arms
/// cv 0.091 → 0.018; with the full model 0.150 → 0.030). The margin: camera 3 passes with
/// the threshold from 0.18 to 0.20 with either model (at 0.22 his track shows her in 3 frames
/// with lite; at 0.17 in 1 with full). Decoded at a short side of 480, 544 or 640
/// (`RIGCAST_TEST_DECODE_SIDE`, `RIGCAST_TEST_MODEL`) both cameras pass with either model. At
/// 480 and 640 with full the man's track was lost for one frame at the crossing's start and his
/// limb lengths were measured afresh from the misreading (upper arms cv 0.18 and 0.23); a person
/// back in their slot within half a second now keeps them (`stages.rs`; 0.038 and 0.034).
#[test]
fn two_performers_in_cameras_1_and_3() {
    check_cameras("two-person, cameras 1 and 3", &[1, 3]);
}

/// The same bounds with the full landmark model, on all four cameras. It reads camera 3's
/// crossing differently: there the man's crops slide onto the woman for most of frames 80–99
/// and the beside crops are not always enough; the crops with her face hidden find him
/// (before them: 97 % coverage, one frame showing her, with the threshold at 0.17).
#[test]
fn two_performers_with_the_full_model() {
    check_cameras_with(
        "two-person, full model",
        &[1, 2, 3, 4],
        Some(ModelKind::Full),
    );
}

fn check_cameras(test: &str, cameras: &[u32]) {
    check_cameras_with(test, cameras, None);
}

/// The tracked people's crops run in one batch give what one run per crop gives: on camera
/// 2's two performers (crops where the tracker put them after 10 frames), every landmark of
/// both people agrees within 0.01 px / 0.1 mm, and presence within 1e-4. The installed pruned
/// models take batches (`scripts/prune_landmark_model.py` leaves their batch dimension open).
#[test]
fn a_batch_of_two_crops_gives_what_two_single_runs_give() {
    let Some(assets) = assets_or_skip("batched landmark runs") else {
        return;
    };
    let config = PipelineConfig {
        assets: assets.clone(),
        ..PipelineConfig::default()
    };
    let path = assets.pose2sim_multi_video(2);
    let mut source = FfmpegSource::open_at(&path, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut pipeline = PosePipeline::new(&config).unwrap();
    let mut frame = RgbFrame::default();
    for _ in 0..10 {
        assert!(source.next_frame(&mut frame).unwrap());
        pipeline.process_frame(&frame).unwrap();
    }
    let tracker = pipeline.tracker_mut();
    let rois: Vec<_> = (0..2)
        .map(|s| tracker.roi(s).expect("two people tracked"))
        .collect();
    let library = assets.runtime_library();
    let file = assets.landmark_model(config.model);
    let mut model = LandmarkModel::load(&library, &file, 2, 2).unwrap();
    assert_eq!(
        model.max_batch(),
        2,
        "{} has a fixed batch dimension: rerun scripts/setup-vision.sh",
        file.display()
    );
    let mut single = [Landmarks::default(); 2];
    for (roi, out) in rois.iter().zip(single.iter_mut()) {
        model.infer(&frame, roi, out).unwrap();
    }
    let mut batched = [Landmarks::default(); 2];
    model.infer_batch(&frame, &rois, &mut batched).unwrap();
    for (s, b) in single.iter().zip(&batched) {
        assert!((s.presence - b.presence).abs() < 1e-4);
        for i in 0..s.image.len() {
            assert!(
                (s.image[i] - b.image[i]).abs().max_element() < 1e-2,
                "landmark {i}"
            );
            assert!(
                (s.world[i] - b.world[i]).abs().max_element() < 1e-4,
                "landmark {i}"
            );
        }
    }
    // The two crops show two different people: a batch that repeated one would fail here.
    let hips = |lm: &Landmarks| Vec2::new(lm.image[idx::LEFT_HIP].x, lm.image[idx::LEFT_HIP].y);
    assert!(hips(&batched[0]).distance(hips(&batched[1])) > 50.0);
}
