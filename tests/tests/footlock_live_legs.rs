//! Issue 35, live: the legs of a character under the causal foot lock stay the performer's,
//! measured through the real server. One server replays the first labelled walk (found by its
//! motion; today the CMU 131_01 walk) onto each labelled human character twice, with the foot lock on and off (the same source sample drives both
//! in the same tick: their frames carry the same capture time). A version 2 client rebuilds
//! both by its own forward kinematics of the wire skeleton; per character:
//! - thigh, shin and foot (ankle to toes) directions of the locked character against the
//!   unlocked one (the source's directions as retargeted; the offline retarget keeps them
//!   within 2° mean of the source's), mean and 95th percentile;
//! - planted-foot drift: the horizontal move per frame of the joint the foot stands on (its
//!   labelled foot or toe joint, the lower on the frame before) while the lock's `footplants`
//!   messages show the foot planted (both frames), cm of a 1.75 m body, as the offline measure
//!   judges it (a foot rolling over its ball moves its ankle without sliding); the move of
//!   every foot joint printed beside it;
//! - feet on the floor: on those frames, the 95th percentile of how far the foot's lowest
//!   joint stands from its height in the character's own rest (authored standing on y = 0).
//!
//! Issue 35's bounds: thigh and shin 3° mean / 8° p95, foot 5° / 15°, drift ≤ 0.05 cm/frame,
//! floor ≤ 1 cm. Not met yet: run with `--ignored` for the table (`cargo test -p
//! rigcast-tests --test footlock_live_legs -- --ignored --nocapture`). Last measured, three
//! runs at load 10-11 (60 Hz ticks, 348-351 paired frames), with the live lock rolling a foot
//! onto its ball as far as the source's heel rises, turning it on its ball and standing it
//! flat about its heel: X Bot thigh 2.0-2.3/6.4-7.4°, shin 1.8-2.1/6.3-7.3°, foot
//! 21.3-21.8/33.8-34.9°, drift 0.015-0.027 cm/frame (every foot joint 0.067-0.079: ankles
//! roll), floor 0.61-0.87 cm; UE-style mannequin 2.6-3.1/8.1-9.2, 2.1-2.5/8.2-8.5,
//! 25.8-26.1/38.6-39.2, 0.019-0.031, 0.66-1.08; Quaternius Casual (no toes) 2.6-3.2/8.5-10.8,
//! 2.4-2.8/9.2-10.2, 0.007-0.013, 0.95-1.29; the robot (no toes) 7.0-8.4/26.4-30.4,
//! 3.5-4.0/13.1-15.5, 0.010-0.015, 2.52-3.47 (its left foot hangs 20-30 cm above the floor in
//! the retargeted walk while the source's stands: a plant pins it there and blends it down).
//! Before (two runs of the lock before it rolled live, the same day): X Bot drift
//! 0.131-0.158, floor 0.52-0.69; mannequin 0.146-0.176, 0.38-0.77; Casual 0.004-0.033,
//! 0.43-1.22; robot 0.005-0.033, 1.01-2.89: the ball slid back under a held ankle while the
//! heel rose, and swung about it when the foot turned. The live lock pitches planted feet
//! flat as it learns the stance (the foot's direction: a foot bone pitched differently at
//! rest carries that pitch to stand flat), two planted feet share their disagreement through
//! the legs, a plant's first frames blend onto the pin (drift per 60 Hz frame), and the
//! figures swing from run to run with the server's timing on a loaded machine.
//! Skips when the shared data is absent.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::time::{Duration, Instant};

use glam::Vec3;
use rigcast_protocol::control::BoneInfo;
use rigcast_protocol::frame::DecodedFrame;
use rigcast_protocol::ServerMessage;
use rigcast_server::{PerformerSpec, ServerConfig};
use rigcast_tests::*;

/// How long the walk is watched.
const WATCH: Duration = Duration::from_secs(6);

/// Half the standing height of the 1.75 m body drift and floor are normalised to.
const LEG_OF_175_CM_BODY: f32 = 0.875;

/// One subject as the client saw it.
#[derive(Default)]
struct Seen {
    bones: Vec<BoneInfo>,
    frames: Vec<DecodedFrame>,
    /// (frame seq, per foot bone: planted) from the `footplants` messages.
    plants: Vec<(u64, Vec<(String, bool)>)>,
}

/// Streams `WATCH` of the first labelled walk (found by its motion; one server streams it onto
/// every character, so one walk) onto every labelled human rig with legs (their rests stand on
/// y = 0; the foot's direction is judged where toes are labelled), locked and free; per target
/// (its labels, locked, free).
async fn stream() -> Option<Vec<(Labelled, Seen, Seen)>> {
    let (_, walk, _) = first_walk()?;
    let targets = human_rigs();
    if targets.is_empty() {
        return None;
    }
    let mut performers = Vec::new();
    for rig in &targets {
        let path = rig.path.clone();
        for lock in [true, false] {
            performers.push(PerformerSpec {
                name: Some(format!("{}-{lock}", performers.len())),
                foot_lock: Some(lock),
                ..PerformerSpec::target_file(path.clone())
            });
        }
    }
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz: 60.0,
        sources: vec![clip_source(walk)],
        performers,
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let mut ws = connect(&format!("ws://{}/v1/stream", server.local_addr())).await;
    send_text(&mut ws, r#"{"type":"set_protocol","version":2}"#).await;
    let mut seen: HashMap<u32, Seen> = HashMap::new();
    let mut ids: HashMap<String, u32> = HashMap::new();
    let t0 = Instant::now();
    while let Some(left) = WATCH.checked_sub(t0.elapsed()) {
        match next(&mut ws, left).await {
            Some(Incoming::Json(ServerMessage::Skeleton {
                subject,
                name,
                bones,
                ..
            })) => {
                ids.insert(name, subject);
                seen.entry(subject).or_default().bones = bones;
            }
            Some(Incoming::Json(ServerMessage::Footplants { subject, seq, feet })) => {
                let states = feet.into_iter().map(|f| (f.bone, f.planted)).collect();
                seen.entry(subject).or_default().plants.push((seq, states));
            }
            Some(Incoming::Frame(f, _)) if f.version == 2 => {
                seen.entry(f.header.subject).or_default().frames.push(f);
            }
            Some(_) => {}
            None => break,
        }
    }
    server.shutdown().await;
    let mut out = Vec::new();
    for (k, rig) in targets.into_iter().enumerate() {
        let mut take = |name: String| {
            let id = ids
                .get(&name)
                .unwrap_or_else(|| panic!("no skeleton for {name}"));
            seen.remove(id).unwrap_or_default()
        };
        let locked = take(format!("{}-true", 2 * k));
        let free = take(format!("{}-false", 2 * k + 1));
        out.push((rig, locked, free));
    }
    Some(out)
}

/// Figures of one character, as `locked_legs_follow_the_source_on_walks_and_runs` offline.
#[derive(Debug)]
struct Legs {
    frames: usize,
    thigh: (f32, f32),
    shin: (f32, f32),
    foot: (f32, f32),
    drift: f32,
    /// The same over every foot joint (an ankle rolling over its ball included).
    joints_drift: f32,
    planted_frames: usize,
    floor_p95: f32,
}

fn mean_p95(mut v: Vec<f32>) -> (f32, f32) {
    if v.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    v.sort_by(f32::total_cmp);
    let mean = v.iter().sum::<f32>() / v.len() as f32;
    (mean, v[(v.len() * 95 / 100).min(v.len() - 1)])
}

fn measure(rig: &Labelled, locked: &Seen, free: &Seen) -> Legs {
    let bones = &locked.bones;
    let index = |role: String| {
        let names = rig.labels[&role].as_array()?;
        (names.iter()).find_map(|n| {
            bones
                .iter()
                .position(|b| Some(b.name.as_str()) == n.as_str())
        })
    };
    // Per side: thigh, shin and foot joints, and the toes where labelled.
    let legs: Vec<([usize; 3], Option<usize>)> = ["L", "R"]
        .iter()
        .map(|s| {
            let joints = ["upperLeg", "lowerLeg", "foot"].map(|r| {
                index(format!("{r}.{s}")).unwrap_or_else(|| {
                    panic!("{}: {r}.{s} not labelled in the wire skeleton", rig.rel)
                })
            });
            (joints, index(format!("toes.{s}")))
        })
        .collect();
    let rest = wire_rest_positions(bones);
    let leg_length = legs
        .iter()
        .map(|(l, _)| (rest[l[1]] - rest[l[0]]).length() + (rest[l[2]] - rest[l[1]]).length())
        .sum::<f32>()
        / legs.len() as f32;
    let body = LEG_OF_175_CM_BODY / leg_length;
    // The free character's frames by capture time: the same source sample.
    let free_at: HashMap<u64, &DecodedFrame> = (free.frames.iter())
        .filter(|f| f.header.capture_nanos != 0)
        .map(|f| (f.header.capture_nanos, f))
        .collect();
    // Each locked frame's planted flags per leg, from the messages (a state holds until the
    // next message).
    let planted_at = |seq: u64, foot: usize| -> bool {
        let name = &bones[foot].name;
        (locked.plants.iter().rev())
            .find(|(s, _)| *s <= seq)
            .and_then(|(_, feet)| feet.iter().find(|(b, _)| b == name))
            .is_some_and(|(_, p)| *p)
    };
    let mut errors: [Vec<f32>; 3] = Default::default();
    let (mut drift_sum, mut drift_n) = (0.0f32, 0usize);
    let (mut all_sum, mut all_n) = (0.0f32, 0usize);
    let mut off_floor = Vec::new();
    let mut frames = 0;
    let mut last: Option<(u64, Vec<Vec3>)> = None;
    for f in &locked.frames {
        let w = wire_fk(bones, f);
        if let Some(g) = free_at.get(&f.header.capture_nanos) {
            frames += 1;
            let v = wire_fk(&free.bones, g);
            for (l, toes) in &legs {
                let chain = [Some(l[0]), Some(l[1]), Some(l[2]), *toes];
                for k in 0..3 {
                    let (Some(a0), Some(a1)) = (chain[k], chain[k + 1]) else {
                        continue;
                    };
                    let (a, b) = (w[a1] - w[a0], v[a1] - v[a0]);
                    if a.length() > 1e-6 && b.length() > 1e-6 {
                        errors[k].push(a.angle_between(b).to_degrees());
                    }
                }
            }
        }
        for (l, toes) in &legs {
            if !planted_at(f.header.seq, l[2]) {
                continue;
            }
            let joints: Vec<usize> = [Some(l[2]), *toes].into_iter().flatten().collect();
            let lowest = (joints.iter().map(|&j| w[j].y - rest[j].y)).fold(f32::INFINITY, f32::min);
            off_floor.push(lowest.abs() * 100.0 * body);
            if let Some((seq, before)) = &last {
                if *seq + 1 == f.header.seq && planted_at(*seq, l[2]) {
                    let moved = |j: usize| {
                        let d = w[j] - before[j];
                        Vec3::new(d.x, 0.0, d.z).length() * 100.0 * body
                    };
                    // The joint the foot stands on: the lowest on the frame before.
                    let contact = (joints.iter().copied())
                        .min_by(|&a, &b| before[a].y.total_cmp(&before[b].y))
                        .unwrap_or(l[2]);
                    drift_sum += moved(contact);
                    drift_n += 1;
                    for &j in &joints {
                        all_sum += moved(j);
                        all_n += 1;
                    }
                }
            }
        }
        last = Some((f.header.seq, w));
    }
    let [thigh, shin, foot] = errors.map(mean_p95);
    let planted_frames = off_floor.len();
    off_floor.sort_by(f32::total_cmp);
    Legs {
        frames,
        thigh,
        shin,
        foot,
        drift: drift_sum / drift_n.max(1) as f32,
        joints_drift: all_sum / all_n.max(1) as f32,
        planted_frames,
        floor_p95: off_floor
            .get(planted_frames * 95 / 100)
            .copied()
            .unwrap_or(f32::NAN),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "issue 35's bounds are not met live yet; the test prints the table per character"]
async fn live_locked_legs_follow_the_source_on_a_walk() {
    let Some(streams) = stream().await else {
        return;
    };
    let mut failures = Vec::new();
    println!(
        "{:<44} {:>6} {:>11} {:>11} {:>11} {:>7} {:>7} {:>7}",
        "target (live, the first walk)",
        "frames",
        "thigh°",
        "shin°",
        "foot°",
        "drift",
        "floor",
        "(drift)"
    );
    for (rig, locked, free) in &streams {
        let rel = &rig.rel;
        let f = measure(rig, locked, free);
        let pair = |(m, p): (f32, f32)| format!("{m:.1}/{p:.1}");
        println!(
            "{rel:<44} {:>6} {:>11} {:>11} {:>11} {:>7.3} {:>7.2} {:>7.3}  ({} planted foot-frames)",
            f.frames,
            pair(f.thigh),
            pair(f.shin),
            pair(f.foot),
            f.drift,
            f.floor_p95,
            f.joints_drift,
            f.planted_frames
        );
        // Enough to judge: seconds of paired frames and plants on both feet.
        // (Every character judged before the test fails.)
        if f.frames < 120 || f.planted_frames < 60 {
            failures.push(format!("{rel}: too little to judge: {f:?}"));
            continue;
        }
        let within = |(m, p): (f32, f32), bm: f32, bp: f32| m <= bm && p <= bp;
        if !(within(f.thigh, 3.0, 8.0) && within(f.shin, 3.0, 8.0)) {
            failures.push(format!("{rel}: thigh {:?} shin {:?}", f.thigh, f.shin));
        }
        // A character without labelled toes has no foot direction to judge.
        if !f.foot.0.is_nan() && !within(f.foot, 5.0, 15.0) {
            failures.push(format!("{rel}: foot {:?}", f.foot));
        }
        if !(f.drift <= 0.05) {
            failures.push(format!("{rel}: drift {:.3} cm/frame", f.drift));
        }
        if !(f.floor_p95 <= 1.0) {
            failures.push(format!("{rel}: planted feet {:.2} cm off", f.floor_p95));
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
