//! Two people from one video drive two characters through the real server: `rigcast serve`
//! with `[[sources]] kind = "video"` entries for persons `#0` (a plain entry) and `#1` of the
//! pose2sim two-person footage (real model, real decoder), two performers on two different rigs
//! (the built-in mannequin and the first labelled human character of the shared data), a real
//! WebSocket client.
//!
//! What is known independently of the server: the same footage run through the landmark
//! pipeline offline, in this process, gives each person's knee bend per video frame straight
//! from their world landmarks (no solver, no mapping, no fan-out). Each character's knees,
//! read off the wire, must follow its own person's knees and not the other's. Frames are put
//! on the video's timeline by their capture time (a paced file is stamped with its frames' due
//! times, anchored at the first frame).
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::time::Duration;

use glam::{Quat, Vec3};
use rigcast_protocol::ServerMessage;
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, PipelineConfig, PosePipeline, RgbFrame, VisionAssets,
};
use rigcast_tests::*;

/// Output rate of the served run. 30 Hz, not the 60 Hz default: the model runs on the same
/// two cores, and 30 Hz is what a character driven from a camera is usually shown at.
const RATE_HZ: f64 = 30.0;
/// The footage: 60 fps, 100 frames.
const VIDEO_FPS: f64 = 60.0;

/// Knee bend (radians; 0 = straight) of the left and right leg, from world landmarks.
fn knee_bends(world: &[Vec3]) -> f32 {
    let bend = |hip: usize, knee: usize, ankle: usize| {
        let thigh = world[knee] - world[hip];
        let shin = world[ankle] - world[knee];
        thigh.angle_between(shin)
    };
    bend(idx::LEFT_HIP, idx::LEFT_KNEE, idx::LEFT_ANKLE)
        + bend(idx::RIGHT_HIP, idx::RIGHT_KNEE, idx::RIGHT_ANKLE)
}

/// Each person's knee bend per video frame (`None` where not seen), offline.
fn offline_knees(assets: &VisionAssets, video: &std::path::Path) -> [Vec<Option<f32>>; 2] {
    let config = PipelineConfig {
        assets: assets.clone(),
        ..PipelineConfig::default()
    };
    let mut frames = FfmpegSource::open_at(video, DecodeSize::FOR_MODEL, VIDEO_FPS).unwrap();
    let mut pipeline = PosePipeline::new(&config).unwrap();
    let mut frame = RgbFrame::default();
    let mut out = [Vec::new(), Vec::new()];
    while frames.next_frame(&mut frame).unwrap() {
        pipeline.process_frame(&frame).unwrap();
        for (slot, series) in out.iter_mut().enumerate() {
            series.push(pipeline.person(slot).map(|lm| knee_bends(&lm.world)));
        }
    }
    out
}

/// Pearson correlation of paired values.
fn correlation(pairs: &[(f32, f32)]) -> f32 {
    let n = pairs.len() as f32;
    let (ma, mb) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut cov, mut va, mut vb) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        cov += (x - ma) * (y - mb);
        va += (x - ma).powi(2);
        vb += (y - mb).powi(2);
    }
    cov / (va * vb).sqrt().max(1e-12)
}

/// One target as the client saw it.
struct Target {
    id: u32,
    /// Bone indices of the two shins (mapped from BlazePose's lower legs) and their rests.
    shins: Vec<(usize, Quat)>,
    /// Receive times of its frames.
    received: Vec<u64>,
    /// Knee bend by capture time (the last frame per capture wins).
    knees: BTreeMap<u64, f32>,
}

fn quat(v: [f32; 4]) -> Quat {
    Quat::from_xyzw(v[0], v[1], v[2], v[3])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_people_of_one_video_drive_two_targets_at_the_tick_rate() {
    let assets = VisionAssets::from_env();
    let video = assets.pose2sim_multi_video(2);
    if !assets.is_ready() || !video.is_file() {
        eprintln!(
            "SKIP: vision models or the pose2sim footage are not installed in {} (run \
             scripts/setup-vision.sh)",
            assets.root.display()
        );
        return;
    }
    let Some(character) = human_rigs().into_iter().next() else {
        return;
    };
    println!("the second character: {}", character.rel);
    let xbot = character.path;
    let expected = offline_knees(&assets, &video);

    let dir = temp_path("vision-two-people");
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("rigcast.toml");
    std::fs::write(
        &config,
        format!(
            "rate_hz = {RATE_HZ}\n\
             [[sources]]\nkind = \"video\"\npath = {video:?}\n\
             [[sources]]\nkind = \"video\"\npath = {video:?}\nperson = 1\n\
             [[performers]]\nsource = \"multi_cam02\"\ntarget = \"builtin:mannequin\"\n\
             foot_lock = false\n\
             [[performers]]\nsource = \"multi_cam02#1\"\ntarget = {xbot:?}\nfoot_lock = false\n"
        ),
    )
    .unwrap();
    let config_arg = config.to_str().unwrap();
    let server = ServeProcess::start(&["--config", config_arg], dir.join("home"), None);
    let mut ws = connect(&format!("ws://{}/v1/stream", server.addr)).await;
    let (hello, skeletons) = handshake(&mut ws).await;
    let ServerMessage::Hello { subjects, .. } = hello else {
        unreachable!()
    };
    let names: Vec<&str> = subjects.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names.len(), 4, "{names:?}");
    // A plain entry is person #0 (named after the file) and shares the file's pipeline with
    // the `person = 1` entry.
    assert_eq!(&names[..2], ["multi_cam02", "multi_cam02#1"]);
    let mut targets: Vec<Target> = subjects[2..]
        .iter()
        .map(|s| Target {
            id: s.id,
            shins: Vec::new(),
            received: Vec::new(),
            knees: BTreeMap::new(),
        })
        .collect();
    // Which target bones the shins are: from the server's mapping messages.
    let rests: BTreeMap<u32, Vec<Quat>> = skeletons
        .iter()
        .map(|m| match m {
            ServerMessage::Skeleton { subject, bones, .. } => (
                *subject,
                bones.iter().map(|b| quat(b.rest_rotation)).collect(),
            ),
            other => panic!("expected a skeleton, got {other:?}"),
        })
        .collect();
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let mut live_seen = [false; 2];
    let mut status_polled = std::time::Instant::now();
    // Until both videos subjects have ended, then a few seconds more of ticks.
    let mut ended_at: Option<std::time::Instant> = None;
    while std::time::Instant::now() < deadline {
        if ended_at.is_some_and(|t| t.elapsed() > Duration::from_secs(2)) {
            break;
        }
        match next(&mut ws, Duration::from_secs(5)).await {
            Some(Incoming::Json(ServerMessage::Mapping {
                subject, entries, ..
            })) => {
                let t = targets.iter_mut().find(|t| t.id == subject).unwrap();
                t.shins = entries
                    .iter()
                    .enumerate()
                    .filter(|(_, e)| {
                        matches!(e.source.as_deref(), Some("leftLowerLeg" | "rightLowerLeg"))
                    })
                    .map(|(i, _)| (i, rests[&subject][i]))
                    .collect();
            }
            Some(Incoming::Frame(f, at)) => {
                let Some(t) = targets.iter_mut().find(|t| t.id == f.header.subject) else {
                    continue;
                };
                t.received.push(at);
                if t.shins.len() == 2 {
                    let bend: f32 = t
                        .shins
                        .iter()
                        .map(|(i, rest)| rotation_angle(f.rotations[*i], *rest))
                        .sum();
                    t.knees.insert(f.header.capture_nanos, bend);
                }
            }
            Some(Incoming::Json(_)) => {}
            None => panic!("the stream closed or went silent: {:?}", server.output()),
        }
        if status_polled.elapsed() > Duration::from_millis(300) && ended_at.is_none() {
            status_polled = std::time::Instant::now();
            let (_, body) = http_get(server.addr, "/v1/status").await;
            let v: serde_json::Value = serde_json::from_str(&body).unwrap();
            let states: Vec<String> = (0..2)
                .map(|i| {
                    v["subjects"][i]["source"]["state"]
                        .as_str()
                        .unwrap()
                        .to_string()
                })
                .collect();
            for (seen, state) in live_seen.iter_mut().zip(&states) {
                *seen |= state == "live";
            }
            let details: Vec<&str> = (0..2)
                .map(|i| v["subjects"][i]["source"]["detail"].as_str().unwrap())
                .collect();
            if details.iter().all(|d| *d == "end of input") {
                ended_at = Some(std::time::Instant::now());
            }
        }
    }
    assert!(ended_at.is_some(), "the video did not end within 60 s");
    assert_eq!(
        live_seen,
        [true, true],
        "both video subjects were live at some point"
    );

    // Frames per second per target, over the whole run from each one's first frame, judged
    // by `rate_plausible`: never above 1.1 × the tick (timer jitter), not below 0.6 × (the
    // tick skips missed ticks when the model, on the same two cores, starves it).
    for t in &targets {
        let span = (t.received[t.received.len() - 1] - t.received[0]) as f64 * 1e-9;
        let hz = (t.received.len() - 1) as f64 / span;
        eprintln!(
            "target {}: {} frames in {span:.2} s = {hz:.1} Hz",
            t.id,
            t.received.len()
        );
        assert!(span > 3.0, "target {} streamed for only {span:.2} s", t.id);
        assert!(
            rate_plausible(hz, RATE_HZ),
            "target {}: {hz:.1} Hz at {RATE_HZ} Hz",
            t.id
        );
    }

    // Each target's knees follow its own person: the first capture is video frame 0.
    let start = targets
        .iter()
        .filter_map(|t| t.knees.keys().next().copied())
        .min()
        .unwrap();
    for (k, t) in targets.iter().enumerate() {
        // (target knees, person's knees) per video frame where the person was seen.
        let pairs = |person: &[Option<f32>]| -> Vec<(f32, f32)> {
            t.knees
                .iter()
                .filter_map(|(&capture, &bend)| {
                    let frame = ((capture - start) as f64 * 1e-9 * VIDEO_FPS).round() as usize;
                    Some((bend, (*person.get(frame)?)?))
                })
                .collect()
        };
        let (own, other) = (pairs(&expected[k]), pairs(&expected[1 - k]));
        let (c_own, c_other) = (correlation(&own), correlation(&other));
        eprintln!(
            "target {} (person #{k}): {} frames on the video's timeline, knee correlation with \
             #{k} {c_own:.2}, with #{} {c_other:.2}",
            t.id,
            own.len(),
            1 - k
        );
        let n = own.len();
        assert!(
            n >= 40,
            "target {}: only {n} frames on the video's timeline",
            t.id
        );
        // Measured: 0.64-0.66 (mannequin, #0) and 0.86 (X Bot, #1) with their own person,
        // -0.29 to -0.46 with the other one. A target driven by the wrong person, or not
        // moving, fails both bounds.
        assert!(
            c_own > 0.5,
            "target {} does not follow person #{k}: {c_own:.2}",
            t.id
        );
        assert!(
            c_own > c_other + 0.5,
            "target {} follows #{} as well: {c_own:.2} vs {c_other:.2}",
            t.id,
            1 - k
        );
    }
}
