//! Live grafts through the real server on real sockets (issue 13): a replayed upper source
//! (PyMO's expressive "Meredith" walk) drives the built-in mannequin's upper body while the
//! CMU 131_01 walk, looped one stride at a time, drives its legs (`upper = "meredith", lower =
//! "…/cmu_131_01_walk.bvh"`). A WebSocket client and the status API see:
//! - the target streaming at the tick rate (the looping clip moves every tick);
//! - the hips walking on continuously: no jump back at the stride's seam, metres travelled;
//! - the upper body following the upper source: the elbow bends of the mannequin and of the
//!   source frame with the same capture time correlate ≥ 0.9;
//! - the lower body's footplants locked: both feet seen held and free in the status.
//!
//! The pair is named: it is the issue's acceptance pair, and the graft's own judge on other
//! labelled walks fails (server/tests/graft_real.rs, ignored with the figures), so the live
//! bounds hold for it alone today. Skips with a printed reason when the shared data is absent.
#![allow(clippy::unwrap_used)]

use std::collections::HashSet;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rigcast_protocol::control::BoneInfo;
use rigcast_protocol::frame::DecodedFrame;
use rigcast_protocol::ServerMessage;
use rigcast_retarget::{world_transforms, Pose, RawSkeleton, Skeleton, Transform};
use rigcast_server::config::{GraftSpec, LowerSpec, PerformerSpec, ReplaySettings};
use rigcast_server::{ServerConfig, SourceSpec};
use rigcast_tests::*;

const RATE_HZ: f64 = 60.0;

/// PyMO's expressive Meredith walk, the acceptance pair's upper body (named: see above).
const MEREDITH_WALK: &str = "zoo/bvh/sparse_spine_head__pymo_meredith.bvh";

fn skeleton(bones: &[BoneInfo]) -> Skeleton {
    let mut raw = RawSkeleton::default();
    for b in bones {
        let [x, y, z] = b.rest_translation;
        let [qx, qy, qz, qw] = b.rest_rotation;
        let rest = Transform {
            translation: Vec3::new(x, y, z),
            rotation: Quat::from_xyzw(qx, qy, qz, qw),
        };
        raw.add(&b.name, b.parent.map(|p| p as usize), rest);
    }
    Skeleton::build(&raw).unwrap()
}

/// A version 2 frame's pose: every rotation, and the translations of the bones the skeleton
/// message marks `translated`, in bone order.
fn pose(skel: &Skeleton, bones: &[BoneInfo], f: &DecodedFrame) -> Pose {
    let mut p = skel.rest_pose();
    p.rotations.copy_from_slice(&f.rotations);
    let translated = bones.iter().enumerate().filter(|(_, b)| b.translated);
    for ((i, _), t) in translated.zip(&f.translations) {
        p.translations[i] = *t;
    }
    p
}

/// Elbow bend, degrees (shoulder, elbow, wrist joints by name).
fn elbow(skel: &Skeleton, p: &Pose, names: [&str; 3]) -> f32 {
    let w = world_transforms(skel, p);
    let at = |n: &str| w[skel.bone(n).unwrap().index()].translation;
    let (s, e, h) = (at(names[0]), at(names[1]), at(names[2]));
    (e - s).angle_between(h - e).to_degrees()
}

fn pearson(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len() as f32;
    let (ma, mb) = (a.iter().sum::<f32>() / n, b.iter().sum::<f32>() / n);
    let cov: f32 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f32 = a.iter().map(|x| (x - ma) * (x - ma)).sum();
    let vb: f32 = b.iter().map(|y| (y - mb) * (y - mb)).sum();
    cov / (va * vb).sqrt().max(1e-12)
}

fn replay(path: std::path::PathBuf, name: &str) -> SourceSpec {
    SourceSpec::ReplayFile(rigcast_server::config::ReplayFileSpec {
        path,
        name: Some(name.into()),
        settings: ReplaySettings::default(),
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_upper_body_on_a_looping_walk_streams_at_the_tick_rate() {
    let Some([upper, walk]) = shared_data_all([MEREDITH_WALK, CMU_WALK]) else {
        return;
    };
    let graft = GraftSpec {
        upper: "meredith".into(),
        lower: LowerSpec::Clip(walk),
    };
    run(vec![replay(upper, "meredith")], graft, 1.5, None).await;
}

/// The lower body from a second source (the CMU walk replayed: idle, walk, idle, so it
/// travels less in the measured 3 s than the looping stride does). The seconds measured are
/// the stretch of the clip where its hips travel furthest, found from the clip and waited for
/// in the stream: where the clip happened to be when the test got there (how long the server
/// took to start and the client to connect, seconds on a loaded machine) decided before
/// whether the window held the walk or the standing, and whether it crossed the loop's seam
/// (the hips jump back 2.6 m there).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_upper_body_on_a_second_source_streams_at_the_tick_rate() {
    let Some([upper, walk]) = shared_data_all([MEREDITH_WALK, CMU_WALK]) else {
        return;
    };
    let clip = rigcast_sources::load_clip(&walk).unwrap();
    let sources = vec![replay(upper, "meredith"), replay(walk, "walk")];
    let graft = GraftSpec {
        upper: "meredith".into(),
        lower: LowerSpec::Source("walk".into()),
    };
    run(sources, graft, 0.3, Some((1, clip))).await;
}

/// How long the performer is let settle after the measuring starts, and how long is measured.
const SETTLE: Duration = Duration::from_millis(500);
const MEASURED: Duration = Duration::from_secs(3);

/// The frame of `clip` from which its hips travel furthest (flat, first to last) over the
/// measured seconds after [`SETTLE`], within one pass of the clip (never across its end).
fn liveliest_start(clip: &rigcast_retarget::Clip) -> usize {
    let frames = |d: Duration| (d.as_secs_f64() / clip.frame_time_secs).round() as usize;
    let (settle, span) = (frames(SETTLE), frames(SETTLE + MEASURED));
    let root = |k: usize| {
        let t = clip.poses[k].translations[0];
        Vec3::new(t.x, 0.0, t.z)
    };
    (0..clip.poses.len().saturating_sub(span))
        .max_by(|&a, &b| {
            let travel = |k: usize| (root(k + span) - root(k + settle)).length();
            travel(a).total_cmp(&travel(b))
        })
        .expect("a clip longer than the measured seconds")
}

/// Reads the stream until source `id`, replaying `clip`, is within a quarter second after
/// `start` (its frames matched to the clip's; at most two passes of the clip).
async fn wait_for_clip_frame(ws: &mut Ws, id: u32, clip: &rigcast_retarget::Clip, start: usize) {
    let late = (0.25 / clip.frame_time_secs) as usize;
    let t0 = Instant::now();
    let most = Duration::from_secs_f64(2.0 * clip.poses.len() as f64 * clip.frame_time_secs + 5.0);
    while let Some(left) = most.checked_sub(t0.elapsed()) {
        let Some(Incoming::Frame(f, _)) = next(ws, left).await else {
            continue;
        };
        if f.header.subject != id || f.version != 2 {
            continue;
        }
        let (k, off) = best_matching_frame(clip, &f.rotations);
        if off < 0.05 && (start..=start + late).contains(&k) {
            println!(
                "source {id} at {:.2} s of its clip after {:.2} s",
                k as f64 * clip.frame_time_secs,
                t0.elapsed().as_secs_f64()
            );
            return;
        }
    }
    panic!("source {id} never streamed frame {start} of its clip");
}

async fn run(
    sources: Vec<SourceSpec>,
    graft: GraftSpec,
    min_travel_m: f32,
    lower_clip: Option<(u32, rigcast_retarget::Clip)>,
) {
    let inputs = match &graft.lower {
        LowerSpec::Source(l) => vec![graft.upper.clone(), l.clone()],
        LowerSpec::Clip(_) => vec![graft.upper.clone()],
    };
    let target_id = sources.len() as u32;
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz: RATE_HZ,
        sources,
        performers: vec![PerformerSpec {
            sources: inputs,
            graft: Some(graft),
            ..PerformerSpec::target_file("builtin:mannequin")
        }],
        mapping_cache_dir: None,
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let mut ws = connect(&server.stream_url()).await;
    let (_, skeletons) = handshake(&mut ws).await;
    // Version 2 frames carry the hips' translation (the mannequin's root bone stays put).
    send_text(&mut ws, r#"{"type":"set_protocol","version":2}"#).await;
    let bones = |id: u32| {
        skeletons
            .iter()
            .find_map(|m| match m {
                ServerMessage::Skeleton { subject, bones, .. } if *subject == id => {
                    Some(bones.clone())
                }
                _ => None,
            })
            .unwrap()
    };
    let (source_bones, target_bones) = (bones(0), bones(target_id));
    let (source_skel, target_skel) = (skeleton(&source_bones), skeleton(&target_bones));
    let pelvis = target_skel.bone("pelvis").unwrap().index();
    // Measured once the target's mapping is built (a `mapping` message for it: in the state a
    // new client is sent, or when the mapper hands it over). A fixed wait for it was a window
    // a loaded machine's debug build could miss: the target then streamed its rest pose into
    // the measured seconds (a jump in the hips when the mapping came, a flat elbow).
    let t0 = Instant::now();
    loop {
        let left = Duration::from_secs(60).saturating_sub(t0.elapsed());
        match next_json(&mut ws, left).await {
            Some(ServerMessage::Mapping { subject, .. }) if subject == target_id => break,
            Some(_) => {}
            None => panic!("no mapping for the target within 60 s"),
        }
    }
    println!("mapping built after {:.2} s", t0.elapsed().as_secs_f64());
    if let Some((id, clip)) = &lower_clip {
        wait_for_clip_frame(&mut ws, *id, clip, liveliest_start(clip)).await;
    }
    // The status, polled while frames stream: which feet the lock holds.
    let seen = Arc::new(Mutex::new(HashSet::<(String, bool)>::new()));
    let poller = {
        let (seen, addr) = (seen.clone(), server.local_addr());
        tokio::spawn(async move {
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_millis(3500) {
                let (_, body) = http_get(addr, "/v1/status").await;
                let v: serde_json::Value = serde_json::from_str(&body).unwrap();
                for f in v["subjects"][target_id as usize]["footplants"]
                    .as_array()
                    .into_iter()
                    .flatten()
                {
                    let key = (
                        f["bone"].as_str().unwrap().to_string(),
                        f["planted"].as_bool().unwrap(),
                    );
                    seen.lock().unwrap().insert(key);
                }
                tokio::time::sleep(Duration::from_millis(25)).await;
            }
        })
    };
    // The performer takes the mapping at its next tick; let the splice settle, then measure.
    collect_frames(&mut ws, SETTLE).await;
    let frames = collect_frames(&mut ws, MEASURED).await;
    poller.await.unwrap();
    let target: Vec<_> = frames
        .iter()
        .filter(|(f, _)| f.header.subject == target_id && f.version == 2)
        .cloned()
        .collect();
    let rate = measured_rate(&target);
    println!("target frames {} at {rate:.1} Hz", target.len());
    assert!(rate_plausible(rate, RATE_HZ), "{rate:.1} Hz");

    // The hips walk on, continuously.
    let roots: Vec<Vec3> = target
        .iter()
        .map(|(f, _)| {
            world_transforms(&target_skel, &pose(&target_skel, &target_bones, f))[pelvis]
                .translation
        })
        .collect();
    let flat = |v: Vec3| Vec3::new(v.x, 0.0, v.z);
    // Each step between two frames per tick of the motion's time between them: from when
    // each was encoded, or from when the source poses they were made from were captured where
    // those lie further apart. On a starved machine the server skips ticks, and a replay that
    // did not run for a while hands over a pose further along its clip, so the walk moves on
    // further by the next frame; a jump back at the seam is as large whatever the gap.
    let period = 1.0 / RATE_HZ;
    let (largest_step, gap) = (target.windows(2).zip(roots.windows(2)))
        .map(|(f, r)| {
            let (a, b) = (&f[0].0.header, &f[1].0.header);
            let encoded = b.send_nanos.saturating_sub(a.send_nanos);
            let captured = b.capture_nanos.saturating_sub(a.capture_nanos);
            let ticks = (encoded.max(captured) as f64 * 1e-9 / period)
                .round()
                .max(1.0);
            (flat(r[1] - r[0]).length() / ticks as f32, ticks)
        })
        .fold((0.0f32, 1.0), |a, b| if b.0 > a.0 { b } else { a });
    let travelled = flat(roots[roots.len() - 1] - roots[0]).length();
    let raw = (roots.windows(2)).map(|r| flat(r[1] - r[0]).length());
    println!(
        "travelled {travelled:.2} m in 3 s, largest step {largest_step:.3} m a tick (over {gap} \
         ticks; {:.3} m between two frames)",
        raw.fold(0.0f32, f32::max)
    );
    assert!(travelled > min_travel_m, "{travelled}");
    assert!(largest_step < 0.1, "a jump of {largest_step} m a tick");

    // The upper body follows the upper source. A target frame carries the newest capture
    // time of its inputs, so with a second (lower) source it is paired with the newest
    // upper frame captured at or before it, not only with an equal stamp.
    let mut source_elbows: Vec<(u64, f32)> = frames
        .iter()
        .filter(|(f, _)| f.header.subject == 0 && f.version == 2)
        .map(|(f, _)| {
            let p = pose(&source_skel, &source_bones, f);
            (
                f.header.capture_nanos,
                elbow(&source_skel, &p, ["LeftArm", "LeftForeArm", "LeftHand"]),
            )
        })
        .collect();
    source_elbows.sort_by_key(|&(c, _)| c);
    let (mut s, mut t) = (Vec::new(), Vec::new());
    for (f, _) in &target {
        let at = source_elbows.partition_point(|&(c, _)| c <= f.header.capture_nanos);
        if at > 0 {
            let p = pose(&target_skel, &target_bones, f);
            s.push(source_elbows[at - 1].1);
            t.push(elbow(
                &target_skel,
                &p,
                ["upperarm_l", "lowerarm_l", "hand_l"],
            ));
        }
    }
    let r = pearson(&s, &t);
    println!("{} paired frames, left elbow correlation {r:.3}", s.len());
    assert!(
        s.len() > target.len() * 9 / 10,
        "{} of {} frames paired",
        s.len(),
        target.len()
    );
    assert!(r >= 0.9, "elbow correlation {r:.3}");

    // The walk's plants are locked on the character: each foot seen held and free.
    let seen = seen.lock().unwrap().clone();
    println!("footplant states seen {seen:?}");
    for foot in ["foot_l", "foot_r"] {
        for planted in [true, false] {
            assert!(
                seen.contains(&(foot.to_string(), planted)),
                "{foot} planted={planted} never seen"
            );
        }
    }
    server.shutdown().await;
}
