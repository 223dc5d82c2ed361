//! [`SharedVision`]: two people of one real video (the pose2sim two-person demo, camera 2),
//! one pipeline thread, one live source each. Each person source must carry exactly its own
//! slot's poses: checked against the pipeline run offline on the same frames.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::time::Duration;

use common::default_config_or_skip;
use rigcast_retarget::approx::quat_angle;
use rigcast_retarget::Pose;
use rigcast_sources::live::{LiveSource, SourceState};
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, PipelineConfig, PosePipeline, RgbFrame, SharedVision,
    VisionError,
};

/// Takes person `#0` (the woman in front) out of the picture from frame `from` on: everything
/// left of x = 440 and below y = 660 (source pixels) painted black. Offline, her visible
/// landmarks stay within x ≤ 428 and y ≥ 669 over the clip; the man behind her (#1, x 153–835,
/// y 408–1198) keeps most of his body in view.
fn without_person_zero(out: &mut RgbFrame, from: u64) -> bool {
    if out.index >= from {
        let k = out.source_from_frame;
        let (x_end, y_start) = ((440.0 / k) as usize, (660.0 / k) as usize);
        let w = out.width as usize;
        for y in y_start.min(out.height as usize)..out.height as usize {
            out.data[(y * w) * 3..(y * w + x_end.min(w)) * 3].fill(0);
        }
    }
    true
}

/// Largest bone rotation difference between two poses, radians.
fn pose_distance(a: &Pose, b: &Pose) -> f32 {
    a.rotations
        .iter()
        .zip(&b.rotations)
        .map(|(p, q)| quat_angle(*p, *q))
        .fold(0.0, f32::max)
}

/// Each slot's pose on every frame of the video (`None` where the slot saw nobody), running
/// the pipeline offline.
fn offline_poses(config: &PipelineConfig, video: &std::path::Path) -> Vec<Vec<Option<Pose>>> {
    let mut frames = FfmpegSource::open_at(video, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let mut pipeline = PosePipeline::new(config).unwrap();
    let mut frame = RgbFrame::default();
    let mut out = vec![Vec::new(), Vec::new()];
    while frames.next_frame(&mut frame).unwrap() {
        pipeline.process_frame(&frame).unwrap();
        for (slot, poses) in out.iter_mut().enumerate() {
            poses.push(
                pipeline
                    .person(slot)
                    .map(|_| pipeline.pose(slot).unwrap().clone()),
            );
        }
    }
    out
}

/// The frames of `offline` whose pose is within `tolerance` (radians) of `pose`.
fn frames_like(offline: &[Option<Pose>], pose: &Pose, tolerance: f32) -> Vec<usize> {
    let near = |p: &Option<Pose>| {
        p.as_ref()
            .is_some_and(|p| pose_distance(pose, p) < tolerance)
    };
    (0..offline.len()).filter(|&i| near(&offline[i])).collect()
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
            // Only the end of input ends the read: a loaded machine can leave a person unseen
            // for over a second of wall time, which reports them lost in between.
            None if source.status().detail == "end of input" => break,
            None => {}
        }
    }
    let status = source.status();
    (poses, status.state, status.detail)
}

#[test]
fn each_person_source_carries_its_own_slot_of_one_shared_pipeline() {
    let Some((assets, config)) = default_config_or_skip("shared vision") else {
        return;
    };
    let video = assets.pose2sim_multi_video(2);
    let expected = offline_poses(&config, &video);
    let seen = |slot: &Vec<Option<Pose>>| slot.iter().flatten().count();
    assert!(
        expected.iter().all(|p| seen(p) >= 95),
        "offline: {:?}",
        expected.iter().map(seen).collect::<Vec<_>>()
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
        assert_eq!(
            (*state, detail.as_str()),
            (SourceState::Lost, "end of input")
        );
        assert_own_poses_in_order(slot, poses, &expected);
    }
    // The two people move differently.
    let both = (40..)
        .find(|&i| expected.iter().all(|e| e[i].is_some()))
        .unwrap();
    let at = |slot: usize| expected[slot][both].as_ref().unwrap();
    let d = pose_distance(at(0), at(1));
    assert!(d > 0.2, "the two subjects' poses differ by only {d} rad");
}

/// What a person source must have carried, however fast its reader was: only its own slot's
/// poses, each the offline pose of a frame, in the video's order (frames taken in turn, each
/// the earliest that fits after the last: two still frames may read alike within the model's
/// run-to-run noise), and the newest one (latest pose wins: a reader may skip frames, never the
/// last publication). How many frames a reader skips depends on how the threads are
/// scheduled, so it is printed, not bounded.
fn assert_own_poses_in_order(slot: usize, poses: &[Pose], expected: &[Vec<Option<Pose>>]) {
    const SAME: f32 = 0.01; // radians; ONNX Runtime's run-to-run noise is ~1e-3
    let other_matches = poses
        .iter()
        .filter(|p| !frames_like(&expected[1 - slot], p, SAME).is_empty())
        .count();
    eprintln!(
        "#{slot}: {} of {} frames, {other_matches} like the other",
        poses.len(),
        expected[slot].len()
    );
    assert_eq!(other_matches, 0, "#{slot} carried the other person's poses");
    let mut frame = 0;
    for (k, pose) in poses.iter().enumerate() {
        let like = frames_like(&expected[slot], pose, SAME);
        assert!(
            !like.is_empty(),
            "#{slot}: pose {k} is no offline pose of its slot"
        );
        frame = *like
            .iter()
            .find(|&&i| i >= frame)
            .unwrap_or_else(|| panic!("#{slot}: pose {k} is of frames {like:?}, before {frame}"));
    }
    if expected[slot].last().is_some_and(Option::is_some) {
        let last = expected[slot].len() - 1;
        let newest = poses.last().map(|p| frames_like(&expected[slot], p, SAME));
        assert!(
            newest.is_some_and(|like| like.contains(&last)),
            "#{slot}: the last frame's pose never reached the reader"
        );
    }
}

/// How one person source's subject fared.
struct Fate {
    /// Frames produced from video frame [`LATE_FRAME`] on.
    late_frames: usize,
    /// The video frame of the newest pose produced.
    last_frame: Option<u64>,
    /// Every distinct "state: detail" in order.
    details: Vec<String>,
    final_state: SourceState,
}

/// Person #0 is taken out of the picture from this video frame on.
const CUT_FRAME: u64 = 30;
/// Frames from here on are "late in the clip", well after the cut.
const LATE_FRAME: f64 = 45.0;

/// Reads `source` until its input ends. A paced file stamps each frame with its due time, so
/// the video frame of a produced pose is its capture time after `first_capture` × 60 fps.
fn follow(mut source: impl LiveSource, first_capture: &std::sync::Mutex<Option<u64>>) -> Fate {
    let mut pose = source.skeleton().unwrap().rest_pose();
    let mut fate = Fate {
        late_frames: 0,
        last_frame: None,
        details: Vec::new(),
        final_state: SourceState::Connecting,
    };
    for _ in 0..4000 {
        if let Some(meta) = source
            .next_frame(Duration::from_millis(50), &mut pose)
            .unwrap()
        {
            // Both people are seen in frame 0, so the earliest capture of either is frame 0.
            let first = *first_capture
                .lock()
                .unwrap()
                .get_or_insert(meta.capture_nanos);
            let frame = meta.capture_nanos.saturating_sub(first) as f64 * 1e-9 * 60.0;
            fate.late_frames += usize::from(frame.round() >= LATE_FRAME);
            fate.last_frame = Some(frame.round() as u64);
        }
        let status = source.status();
        let note = format!("{:?}: {}", status.state, status.detail);
        if fate.details.last() != Some(&note) {
            fate.details.push(note);
        }
        fate.final_state = status.state;
        if status.detail == "end of input" {
            break;
        }
    }
    fate
}

#[test]
fn a_person_leaving_the_view_loses_only_their_own_subject() {
    let Some((assets, config)) = default_config_or_skip("shared vision, one person leaves") else {
        return;
    };
    let video = assets.pose2sim_multi_video(2);
    let inner = FfmpegSource::open_at(&video, DecodeSize::FOR_MODEL, 30.0).unwrap();
    let last_read = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let frames = common::Edited {
        inner,
        edit: {
            let last_read = last_read.clone();
            move |f: &mut RgbFrame| {
                last_read.store(f.index, std::sync::atomic::Ordering::Relaxed);
                without_person_zero(f, CUT_FRAME)
            }
        },
    };
    // Paced: 100 frames at 60 fps take at least 1.7 s, so a second without person #0 is
    // within the clip even if the pipeline keeps up.
    let shared = SharedVision::new(Box::new(frames), PosePipeline::new(&config).unwrap(), true);
    let sources = [
        shared.person(0, "#0").unwrap(),
        shared.person(1, "#1").unwrap(),
    ];
    drop(shared);
    let first_capture = std::sync::Mutex::new(None);
    let fates: Vec<Fate> = std::thread::scope(|s| {
        let handles: Vec<_> = sources
            .into_iter()
            .map(|src| {
                let first_capture = &first_capture;
                s.spawn(move || follow(src, first_capture))
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (slot, f) in fates.iter().enumerate() {
        eprintln!(
            "#{slot}: {} frames late in the clip, {:?}",
            f.late_frames, f.details
        );
    }
    let (zero, one) = (&fates[0], &fates[1]);
    assert!(
        zero.details.iter().any(|d| d == "Live: no person in view"),
        "#0 never reported that she left: {:?}",
        zero.details
    );
    assert!(
        zero.details.iter().any(|d| d == "Lost: no person in view"),
        "#0 was not lost after a second without her: {:?}",
        zero.details
    );
    assert!(
        one.details
            .iter()
            .all(|d| !d.contains("no person in view") && !d.starts_with("Lost: no")),
        "#1 was affected by #0 leaving: {:?}",
        one.details
    );
    // The man stays in view to the end. How many frames his reader skips depends on how the
    // threads are scheduled (latest pose wins), but never the newest one.
    let last = last_read.load(std::sync::atomic::Ordering::Relaxed);
    assert!(one.late_frames > 0, "#1 stopped before frame {LATE_FRAME}");
    assert_eq!(
        one.last_frame,
        Some(last),
        "#1 stopped before the last frame"
    );
    assert_eq!(
        zero.late_frames, 0,
        "#0 produced poses with her out of view"
    );
    assert_eq!(
        one.final_state,
        SourceState::Lost,
        "end of input makes everyone lost"
    );
}

/// Publishing the tracked people before the finder runs (what the pipeline thread does, so a
/// detector pass never holds up their poses) changes nobody's result: on real footage with
/// one and two people, [`PosePipeline::track_frame`] then [`PosePipeline::find_people`] give
/// every slot the poses [`PosePipeline::process_frame`] gives, and the finder never changes a
/// pose already published by `track_frame`. Checked on frames where the finder did run with
/// someone tracked, so the property is exercised.
#[test]
fn the_finder_never_changes_a_tracked_persons_published_pose() {
    let Some((assets, config)) = default_config_or_skip("publish before the finder") else {
        return;
    };
    let (mut exercised, mut found_later) = (0, 0);
    for video in [assets.pose2sim_video(1), assets.pose2sim_multi_video(2)] {
        let mut frames = FfmpegSource::open_at(&video, DecodeSize::FOR_MODEL, 30.0).unwrap();
        let mut whole = PosePipeline::new(&config).unwrap();
        let mut halves = PosePipeline::new(&config).unwrap();
        let mut frame = RgbFrame::default();
        let mut published: Vec<Option<Pose>> = vec![None; halves.num_people()];
        let mut seen = 0;
        while frames.next_frame(&mut frame).unwrap() {
            whole.process_frame(&frame).unwrap();
            halves.track_frame(&frame).unwrap();
            for (slot, p) in published.iter_mut().enumerate() {
                *p = halves
                    .person(slot)
                    .map(|_| halves.pose(slot).unwrap().clone());
            }
            let detections = halves.stats().detections;
            found_later += usize::from(halves.find_people(&frame).unwrap());
            let finder_ran = halves.stats().detections > detections;
            exercised += usize::from(finder_ran && published.iter().any(Option::is_some));
            for (slot, p) in published.iter().enumerate() {
                if let Some(p) = p {
                    assert!(
                        halves.person(slot).is_some(),
                        "#{slot} unseen after the finder"
                    );
                    let now = &halves.pose(slot).unwrap().rotations;
                    assert!(
                        p.rotations == *now,
                        "the finder changed #{slot}'s published pose"
                    );
                }
                let (a, b) = (whole.person(slot).is_some(), halves.person(slot).is_some());
                assert_eq!(
                    a, b,
                    "frame {}: #{slot} seen {a} whole, {b} in halves",
                    frame.index
                );
                if a {
                    seen += 1;
                    let d = pose_distance(whole.pose(slot).unwrap(), halves.pose(slot).unwrap());
                    // ONNX Runtime's threads make two runs of one pipeline differ by ~1e-3 rad.
                    assert!(
                        d < 0.01,
                        "frame {}: #{slot} differs by {d} rad",
                        frame.index
                    );
                }
            }
        }
        eprintln!(
            "{}: {seen} poses alike; so far the finder ran on {exercised} frames with \
             someone published before it and found someone on {found_later}",
            video.display()
        );
    }
    assert!(
        exercised >= 5,
        "the finder ran after a publication on {exercised} frames"
    );
    assert!(
        found_later >= 2,
        "the finder found someone on {found_later} frames"
    );
}
