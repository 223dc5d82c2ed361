//! Two performers from one camera, on real footage: the pose2sim two-person demo (a woman in a
//! grey shirt in front, a shirtless man jumping behind her, a bystander at the back; 1088×1920,
//! 60 fps, four cameras), installed by `scripts/setup-vision.sh`.
//!
//! Identity is judged independently of the tracker: by the colour of each person's torso in
//! the decoded picture (grey cloth against bare skin). Each identity slot must keep the torso
//! colour it started with in every frame.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use common::{assets_or_skip, cv, side_swaps, SEGMENTS};
use glam::{Vec2, Vec3};
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, LandmarkModel, Landmarks, ModelKind, PipelineConfig,
    PosePipeline, RgbFrame,
};

/// Mean colour of the torso (a 3×5 grid around the spine, the middle third of the
/// shoulder–hip quad: a torso seen from the side is a thin sliver), from `frame`; landmarks
/// are in source pixels.
fn torso_colour(frame: &RgbFrame, lm: &Landmarks) -> Vec3 {
    let px = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y) / frame.source_from_frame;
    let (ls, rs, lh, rh) = (
        px(idx::LEFT_SHOULDER),
        px(idx::RIGHT_SHOULDER),
        px(idx::LEFT_HIP),
        px(idx::RIGHT_HIP),
    );
    let mut sum = Vec3::ZERO;
    for a in 0..3 {
        for b in 1..=5 {
            let (u, v) = (0.4 + 0.1 * a as f32, b as f32 / 6.0);
            let top = ls.lerp(rs, u);
            let bottom = lh.lerp(rh, u);
            let p = top.lerp(bottom, v);
            let c = frame.pixel(p.x as i32, p.y as i32);
            sum += Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        }
    }
    sum / 15.0
}

struct Person {
    frames: Vec<Option<Landmarks>>,
    colours: Vec<Option<Vec3>>,
}

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

/// Checks `cameras` with `model`, else the model `RIGCAST_TEST_MODEL` names (`full`, …), else
/// the default one.
fn check_cameras_with(test: &str, cameras: &[u32], model: Option<ModelKind>) {
    let Some(assets) = assets_or_skip(test) else {
        return;
    };
    let model = match (model, std::env::var("RIGCAST_TEST_MODEL")) {
        (Some(m), _) => m,
        (None, Ok(v)) => v.parse().unwrap(),
        (None, Err(_)) => PipelineConfig::default().model,
    };
    let config = PipelineConfig {
        assets: assets.clone(),
        model,
        ..PipelineConfig::default()
    };
    assert_eq!(
        config.tracker.max_people, 2,
        "the default tracks two people"
    );
    let mut failures = Vec::new();
    for &cam in cameras {
        let path = assets.pose2sim_multi_video(cam);
        let size = match std::env::var("RIGCAST_TEST_DECODE_SIDE") {
            Ok(v) => DecodeSize::ShortSide(v.parse().unwrap()),
            Err(_) => DecodeSize::FOR_MODEL,
        };
        let mut source = FfmpegSource::open_at(&path, size, 30.0).unwrap();
        let mut pipeline = PosePipeline::new(&config).unwrap();
        let mut frame = RgbFrame::default();
        let mut people: Vec<Person> = (0..2)
            .map(|_| Person {
                frames: Vec::new(),
                colours: Vec::new(),
            })
            .collect();
        while source.next_frame(&mut frame).unwrap() {
            pipeline.process_frame(&frame).unwrap();
            for (slot, person) in people.iter_mut().enumerate() {
                let lm = pipeline.person(slot).copied();
                let raw = pipeline.raw_person(slot);
                person.colours.push(raw.map(|lm| torso_colour(&frame, lm)));
                person.frames.push(lm);
            }
        }
        let num_frames = people[0].frames.len();
        let stats = pipeline.stats();
        let mut report = format!("cam{cam}: {num_frames} frames, {stats:?}");
        let mut swaps_seen = 0;
        // The median torso colour of each slot: who that slot is.
        let medians: Vec<Vec3> = people
            .iter()
            .map(|p| {
                let mut c: Vec<Vec3> = p.colours.iter().flatten().copied().collect();
                let mut m = Vec3::ZERO;
                for k in 0..3 {
                    c.sort_by(|a, b| a[k].total_cmp(&b[k]));
                    m[k] = c.get(c.len() / 2).map_or(0.0, |v| v[k]);
                }
                m
            })
            .collect();
        report += &format!(", torso colours {:.0} / {:.0}", medians[0], medians[1]);
        assert!(
            medians[0].distance(medians[1]) > 30.0,
            "{report}: the two slots hold the same person"
        );
        for (slot, person) in people.iter().enumerate() {
            let seen = person.frames.iter().flatten().count();
            let coverage = seen as f32 / num_frames as f32;
            report += &format!(", #{slot} in {:.1}%", coverage * 100.0);
            if coverage < 0.99 {
                failures.push(format!("cam{cam} #{slot} coverage {coverage:.3}"));
            }
            // A frame shows the other person when its colour is nearer the other's median than
            // its own slot's, and no farther from the other's than half the distance between
            // the two medians (the colour halfway between the two identities). A colour nearer
            // the other's median only by a little, and far from both, looks like neither: where
            // the man's torso grid takes in his dark shorts it lies about 90 from both medians
            // (camera 3, frames 89-92), and which median was nearer turned on a few units of
            // his median: the output's heatmap refinement (9e1c547) moved it by 6 and 4 such
            // frames were called hers, frame 92 among them with torso points the same to the
            // bit as without it (112/98/62, 97 from both medians). A slide onto her is still
            // caught: with the tracker's ON_OTHER_BODY at 0.22 his track shows her grey in frames
            // 87 and 90 (19 and 22 from her median, halfway 23; refined, frame 87 at 17 while
            // frame 90 sits at 23 from both).
            let (own, other) = (medians[slot], medians[1 - slot]);
            let halfway = own.distance(other) * 0.5;
            let nearer_other = |c: &&Vec3| c.distance(other) < c.distance(own);
            let swaps = person
                .colours
                .iter()
                .flatten()
                .filter(nearer_other)
                .filter(|c| c.distance(other) <= halfway)
                .count();
            let neither = person.colours.iter().flatten().filter(nearer_other).count() - swaps;
            report += &format!(
                " ({swaps} frames looking like the other, {neither} nearer the other's colour \
                 but like neither)"
            );
            if swaps + neither > 0 {
                let trace: Vec<String> = person
                    .colours
                    .iter()
                    .map(|c| c.map_or("-".into(), |c| format!("{:.0}/{:.0}/{:.0}", c.x, c.y, c.z)))
                    .collect();
                eprintln!("#{slot} torso colours per frame: {}", trace.join(" "));
            }
            if swaps > 0 {
                failures.push(format!(
                    "cam{cam} #{slot}: {swaps} frames show the other person"
                ));
            }
            let found: Vec<&Landmarks> = person.frames.iter().flatten().collect();
            for (name, a, b) in SEGMENTS {
                let lengths: Vec<f32> = found
                    .iter()
                    .map(|lm| lm.world[a].distance(lm.world[b]))
                    .collect();
                let c = cv(&lengths);
                report += &format!(", {name} cv {c:.3}");
                if c > 0.10 {
                    failures.push(format!("cam{cam} #{slot} {name} cv {c:.3}"));
                }
            }
            swaps_seen += side_swaps(&person.frames);
        }
        // Left and right change between two frames only where the tracker took the model's
        // labelling on the evidence of its readings, and that at most once a person: no
        // flicker, no swap unexplained.
        if swaps_seen as u64 > stats.relabels || stats.relabels > people.len() as u64 {
            failures.push(format!(
                "cam{cam}: sides swapped {swaps_seen} times, {} relabels",
                stats.relabels
            ));
        }
        eprintln!("{report}");
    }
    assert!(failures.is_empty(), "{failures:?}");
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
