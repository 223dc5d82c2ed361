//! Hardware-free replay of the vision source: `recordings/vision/pose2sim_cam01.rcr` holds the
//! raw landmark records a live [`VisionSource`] tapped from the first 60 frames of the pose2sim
//! demo footage (cam01), plus the poses the live pipeline produced from them (subject 0).
//! Replaying the landmarks through [`LandmarkReplaySource`] must give those poses again, with
//! no model, runtime or video — these tests run in CI without `scripts/setup-vision.sh`.
//!
//! Regenerate the recording (needs the vision setup):
//! `cargo test -p rigcast-sources --test vision_replay -- --ignored make_pose2sim_cam01_recording`
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use glam::{Quat, Vec3};
use rigcast_retarget::approx::quat_angle;
use rigcast_retarget::Pose;
use rigcast_sources::live::{LiveSource, MemoryTap, RawKind, RawPacket, SourceState};
use rigcast_sources::recording::{read_recording, Recording, RecordingWriter};
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::source::{decode_landmarks, encode_landmarks};
use rigcast_sources::vision::{
    FfmpegSource, LandmarkReplaySource, PipelineConfig, PosePipeline, RgbFrame, VisionError,
    VisionSource,
};

const FRAMES: usize = 60;

fn recording_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/vision/pose2sim_cam01.rcr")
}

fn load() -> Recording {
    read_recording(&std::fs::read(recording_path()).unwrap()[..]).unwrap()
}

/// Serves every recorded frame of `source`; the poses of frames with a person.
fn drain(source: &mut dyn LiveSource) -> Vec<Pose> {
    let mut pose = source.skeleton().unwrap().rest_pose();
    let mut poses = Vec::new();
    for _ in 0..10 * FRAMES {
        match source
            .next_frame(Duration::from_millis(50), &mut pose)
            .unwrap()
        {
            Some(_) => poses.push(pose.clone()),
            None if source.status().state == SourceState::Lost => break,
            None => {}
        }
    }
    assert_eq!(source.status().state, SourceState::Lost, "never finished");
    poses
}

/// Largest component difference between two rotations (either sign of the quaternion). Finer
/// than an angle, whose f32 `acos` cannot resolve below about 1e-3 rad.
fn quat_diff(a: Quat, b: Quat) -> f32 {
    let (a, b) = (glam::Vec4::from(a), glam::Vec4::from(b));
    let d = (a - b).abs().max_element();
    let s = (a + b).abs().max_element();
    d.min(s)
}

fn max_diff(a: &[Pose], b: &[Pose]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| p.rotations.iter().zip(&q.rotations))
        .map(|(x, y)| quat_diff(*x, *y))
        .fold(0.0, f32::max)
}

fn replay(packets: &[RawPacket], config: &PipelineConfig) -> LandmarkReplaySource {
    LandmarkReplaySource::from_packets("test", packets, config, false).unwrap()
}

#[test]
fn replaying_the_landmarks_reproduces_the_live_poses() {
    let rec = load();
    let landmark_packets = rec
        .raw
        .iter()
        .filter(|p| p.kind == RawKind::Landmarks)
        .count();
    assert_eq!(landmark_packets, FRAMES);
    // A person in every one of these frames, so frame records and packets pair up.
    assert_eq!(rec.frames.len(), FRAMES);
    let expected: Vec<Pose> = rec.frames.iter().map(|f| f.pose.clone()).collect();

    let mut source = LandmarkReplaySource::open(
        &recording_path(),
        Some(0),
        &PipelineConfig::default(),
        false,
    )
    .unwrap();
    assert_eq!(source.len(), FRAMES);
    assert_eq!(source.status().state, SourceState::Connecting);
    let skeleton = source.skeleton().unwrap();
    assert_eq!(skeleton.num_bones(), 19);
    assert_eq!(
        rec.skeletons[0].skeleton.fingerprint(),
        skeleton.fingerprint()
    );
    let poses = drain(&mut source);
    assert_eq!(poses.len(), FRAMES);
    // Same stages, same inputs, same times (to the nanosecond): equal up to f32 storage.
    let err = max_diff(&poses, &expected);
    assert!(err < 1e-4, "replay differs from the live poses by {err}");
    for (p, q) in poses.iter().zip(&expected) {
        assert!((p.translations[0] - q.translations[0]).length() < 1e-6);
    }
    assert_eq!(source.status().frames, FRAMES as u64);
    assert_eq!(source.status().dropped, 0);

    // The stages matter: without smoothing (or with the frames' times squashed) the poses
    // differ, so the comparison above would catch a replay that skipped or mistimed a stage.
    let raw = PipelineConfig {
        smoothing: false,
        ..PipelineConfig::default()
    };
    let unsmoothed = drain(&mut replay(&rec.raw, &raw));
    let diff = max_diff(&unsmoothed, &expected);
    assert!(diff > 1e-2, "smoothing changes nothing? {diff}");
    let mut squashed = rec.raw.clone();
    for (i, p) in squashed.iter_mut().enumerate() {
        p.capture_nanos = i as u64 * 1_000_000; // 1000 fps instead of 60
    }
    let diff = max_diff(
        &drain(&mut replay(&squashed, &PipelineConfig::default())),
        &expected,
    );
    assert!(diff > 1e-3, "timing changes nothing? {diff}");
}

#[test]
fn low_confidence_bones_hold_then_ease_during_replay() {
    let rec = load();
    let skeleton = rigcast_sources::vision::blazepose_skeleton().unwrap();
    let forearm = skeleton.bone("leftLowerArm").unwrap();
    let upper = skeleton.bone("leftUpperArm").unwrap();
    // From frame K on, the left wrist jumps 30 cm up and forward: once visible, once not.
    const K: usize = 20;
    let edit = |visibility: Option<f32>| {
        let mut packets = rec.raw.clone();
        for p in packets.iter_mut().skip(K) {
            let mut lm = decode_landmarks(&p.bytes).unwrap();
            lm.world[idx::LEFT_WRIST] += Vec3::new(0.0, -0.3, -0.3);
            lm.image[idx::LEFT_WRIST].y -= 300.0;
            if let Some(v) = visibility {
                lm.image[idx::LEFT_WRIST].w = v;
            }
            encode_landmarks(&lm, &mut p.bytes);
        }
        packets
    };
    let original = drain(&mut replay(&rec.raw, &PipelineConfig::default()));
    let visible = drain(&mut replay(&edit(None), &PipelineConfig::default()));
    let hidden_packets = edit(Some(0.05));
    let mut hidden_source = replay(&hidden_packets, &PipelineConfig::default());
    let mut pose = skeleton.rest_pose();
    let mut hidden = Vec::new();
    let mut confidence = Vec::new();
    while !hidden_source.finished() {
        if hidden_source
            .next_frame(Duration::ZERO, &mut pose)
            .unwrap()
            .is_some()
        {
            hidden.push(pose.clone());
            confidence.push(hidden_source.confidence().to_vec());
        }
    }
    assert_eq!(hidden.len(), FRAMES);

    // A visible jump is followed...
    let moved = quat_angle(
        visible[K + 5].rotation(forearm),
        original[K + 5].rotation(forearm),
    );
    assert!(
        moved > 0.2,
        "visible wrist jump moved the forearm only {moved} rad"
    );
    // ...an invisible one is not: the forearm holds its last confident rotation for the hold
    // time (0.5 s = 30 frames at 60 fps), with a low confidence. The upper arm (whose
    // landmarks stay visible) keeps following the stream's shoulder → elbow direction; only
    // its twist, whose reference is the wrist, stops following.
    let elbow_dir = skeleton.rest()[forearm.index()]
        .translation
        .try_normalize()
        .unwrap();
    let held = hidden[K - 1].rotation(forearm);
    for (i, pose) in hidden.iter().enumerate().take(K + 28).skip(K) {
        assert!(confidence[i][forearm.index()] < 0.3, "frame {i}");
        let a = quat_diff(pose.rotation(forearm), held);
        assert!(a < 1e-5, "frame {i}: forearm moved {a} while invisible");
        let swing = pose.rotation(upper) * elbow_dir;
        let expected = original[i].rotation(upper) * elbow_dir;
        let d = (swing - expected).length();
        assert!(d < 1e-3, "frame {i}: upper arm direction off by {d}");
    }
    let twist_hidden = quat_diff(hidden[K].rotation(upper), original[K].rotation(upper));
    let twist_visible = quat_diff(visible[K].rotation(upper), original[K].rotation(upper));
    assert!(
        twist_hidden * 5.0 < twist_visible,
        "upper arm twisted after an invisible wrist: {twist_hidden} vs visible {twist_visible}"
    );
    // After the hold it eases towards rest, never jumping.
    let last = hidden[FRAMES - 1].rotation(forearm);
    let to_rest = |q: Quat| quat_angle(q, Quat::IDENTITY);
    assert!(
        to_rest(last) < to_rest(held) - 0.02,
        "no ease: {} → {}",
        to_rest(held),
        to_rest(last)
    );
    for (i, w) in hidden[K - 1..].windows(2).enumerate() {
        let step = quat_angle(w[0].rotation(forearm), w[1].rotation(forearm));
        assert!(step < 0.05, "frame {}: forearm jumped {step} rad", K + i);
    }
}

#[test]
fn malformed_and_missing_records_are_reported_not_panicked() {
    let rec = load();
    let mut packets = rec.raw.clone();
    packets[3].bytes.truncate(100);
    packets[7].bytes.push(0);
    let mut source = replay(&packets, &PipelineConfig::default());
    assert_eq!(source.malformed(), 2);
    assert_eq!(source.len(), FRAMES - 2);
    assert_eq!(source.status().dropped, 2);
    assert_eq!(drain(&mut source).len(), FRAMES - 2);

    // Empty records mark frames without a person: no pose, and the smoothing restarts.
    let mut gap = rec.raw.clone();
    for p in &mut gap[30..35] {
        p.bytes.clear();
    }
    assert_eq!(
        drain(&mut replay(&gap, &PipelineConfig::default())).len(),
        FRAMES - 5
    );

    let err = LandmarkReplaySource::from_packets("none", &[], &PipelineConfig::default(), false)
        .unwrap_err();
    assert!(matches!(err, VisionError::Recording { .. }), "{err}");
    let err = LandmarkReplaySource::open(
        Path::new("/nonexistent/x.rcr"),
        None,
        &PipelineConfig::default(),
        false,
    )
    .unwrap_err();
    assert!(err.to_string().contains("/nonexistent/x.rcr"), "{err}");
    // A recording without landmark records (the VMC one) is a clear error naming the file.
    let vmc = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/vmc/humanoid_wave.rcr");
    let err =
        LandmarkReplaySource::open(&vmc, None, &PipelineConfig::default(), false).unwrap_err();
    assert!(err.to_string().contains("humanoid_wave.rcr"), "{err}");
    assert!(err.to_string().contains("no landmark records"), "{err}");
}

#[test]
fn realtime_replay_keeps_the_recorded_pace() {
    let rec = load();
    let packets: Vec<RawPacket> = rec.raw[..13].to_vec(); // 12 intervals = 0.2 s at 60 fps
    let mut source =
        LandmarkReplaySource::from_packets("rt", &packets, &PipelineConfig::default(), true)
            .unwrap();
    let start = std::time::Instant::now();
    assert_eq!(drain(&mut source).len(), 13);
    let secs = start.elapsed().as_secs_f64();
    assert!((0.18..0.6).contains(&secs), "took {secs} s");
}

/// Runs the live source over the first frames of cam01 with a raw tap and writes the tapped
/// landmark stream plus the poses it produced (times from 0) to `out`. Also checks that
/// replaying the tap reproduces the live poses.
fn record_live(out: &Path) {
    let Some(assets) = common::assets_or_skip("make vision recording") else {
        return;
    };
    // The first FRAMES frames.
    let mut read = 0;
    let frames = common::Edited {
        inner: FfmpegSource::open(&assets.pose2sim_video(1)).unwrap(),
        edit: move |_: &mut RgbFrame| {
            read += 1;
            read <= FRAMES
        },
    };
    let config = PipelineConfig {
        assets,
        ..PipelineConfig::default()
    };
    let pipeline = PosePipeline::new(&config).unwrap();
    let mut source = VisionSource::new("video:cam01", Box::new(frames), pipeline, false);
    let tap = MemoryTap::default();
    source.set_raw_tap(Some(Box::new(tap.clone())));
    let live = drain(&mut source);
    let packets = tap.packets.lock().unwrap().clone();
    assert_eq!(packets.len(), FRAMES);
    assert_eq!(
        live.len(),
        FRAMES,
        "person missing in some of the first frames"
    );
    let replayed = drain(&mut replay(&packets, &config));
    let err = max_diff(&live, &replayed);
    assert!(err < 1e-4, "tap replay differs from live by {err}");

    let skeleton = source.skeleton().unwrap();
    write_recording(out, &skeleton, &packets, &live);
}

/// Writes the landmark `packets` (times made relative to the first) and, after each packet
/// with a person, the next of `poses` as subject 0's frame.
fn write_recording(
    out: &Path,
    skeleton: &Arc<rigcast_retarget::Skeleton>,
    packets: &[RawPacket],
    poses: &[Pose],
) {
    let t0 = packets[0].capture_nanos;
    let writer = Arc::new(Mutex::new(
        RecordingWriter::new(std::fs::File::create(out).unwrap()).unwrap(),
    ));
    let mut w = writer.lock().unwrap();
    w.write_skeleton(0, "pose2sim cam01 (BlazePose)", skeleton)
        .unwrap();
    let mut poses = poses.iter();
    for (seq, p) in packets.iter().enumerate() {
        let t = p.capture_nanos - t0;
        w.write_raw(0, p.kind, t, &p.bytes).unwrap();
        if !p.bytes.is_empty() {
            w.write_frame(0, seq as u64, t, poses.next().unwrap())
                .unwrap();
        }
    }
    drop(w);
    Arc::try_unwrap(writer)
        .ok()
        .unwrap()
        .into_inner()
        .unwrap()
        .finish()
        .unwrap();
}

#[test]
#[ignore = "regenerates recordings/vision/pose2sim_cam01.rcr from the real footage"]
fn make_pose2sim_cam01_recording() {
    let path = recording_path();
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    record_live(&path);
    eprintln!("wrote {}", path.display());
}

/// Keeps the recording's landmarks and rewrites its expected poses with what the current
/// stages make of them: for a change to smoothing, lengths or solving, where re-running the
/// model would change the landmarks the other tests are written against.
#[test]
#[ignore = "rewrites the expected poses of recordings/vision/pose2sim_cam01.rcr"]
fn refresh_pose2sim_cam01_poses() {
    let rec = load();
    let packets: Vec<RawPacket> = rec
        .raw
        .iter()
        .filter(|p| p.kind == RawKind::Landmarks)
        .cloned()
        .collect();
    let poses = drain(&mut replay(&packets, &PipelineConfig::default()));
    write_recording(
        &recording_path(),
        &rec.skeletons[0].skeleton,
        &packets,
        &poses,
    );
    eprintln!("rewrote the poses of {}", recording_path().display());
}

#[test]
fn live_tap_replays_to_the_live_poses() {
    // The same check on fresh footage, when the vision setup is present.
    let dir = std::env::temp_dir().join(format!("rigcast-vision-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    record_live(&dir.join("cam01.rcr"));
    let _ = std::fs::remove_dir_all(&dir);
}
