//! A live VMC source in a real server: VMC packets go into the server's UDP port, the
//! retargeted target subject arrives over WebSocket and matches `Mapping::apply` on the same
//! input; when the sender stops the source turns `lost` and the target eases to rest without a
//! jump; when it resumes the source is `live` again and the target follows.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::Quat;
use rigcast_protocol::vmc::VmcEncoder;
use rigcast_protocol::ServerMessage;
use rigcast_retarget::analysis::SkeletonView;
use rigcast_retarget::mapping::{auto_map, MapOptions};
use rigcast_retarget::{Mapping, RetargetOptions};
use rigcast_server::{PerformerSpec, ServerConfig};
use rigcast_tests::*;

const RATE: f64 = 60.0;

/// Sends poses of `clip` (bones named `names`) to `to` at [`RATE`] while `running(elapsed)`:
/// the k-th datagram carries frame `frame(k, elapsed)`, stamped with the elapsed seconds.
fn stream_clip(
    to: std::net::SocketAddr,
    clip: &rigcast_retarget::Clip,
    names: &[String],
    running: impl Fn(Duration) -> bool,
    frame: impl Fn(usize, Duration) -> usize,
) {
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut enc = VmcEncoder::new();
    let t0 = Instant::now();
    let mut k = 0;
    while running(t0.elapsed()) {
        let pose = &clip.poses[frame(k, t0.elapsed())];
        rigcast_tests::send_vmc_pose(
            &socket,
            to,
            &mut enc,
            names,
            pose,
            t0.elapsed().as_secs_f32(),
        );
        k += 1;
        std::thread::sleep(Duration::from_secs_f64(1.0 / RATE));
    }
}

fn max_angle(a: &[Quat], b: &[Quat]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| rotation_angle(x, y))
        .fold(0.0, f32::max)
}

/// Waits for a JSON message matching `f`.
async fn wait_json<T>(
    ws: &mut Ws,
    timeout: Duration,
    mut f: impl FnMut(&ServerMessage) -> Option<T>,
) -> Option<T> {
    let deadline = Instant::now() + timeout;
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match next(ws, left).await? {
            Incoming::Json(m) => {
                if let Some(t) = f(&m) {
                    return Some(t);
                }
            }
            Incoming::Frame(..) => {}
        }
    }
    None
}

fn source_state(m: &ServerMessage) -> Option<String> {
    source_record(m).map(|(state, _)| state)
}

/// (state, detail) of subject 0 in a `source_status` message.
fn source_record(m: &ServerMessage) -> Option<(String, String)> {
    match m {
        ServerMessage::SourceStatus { sources, .. } => sources
            .iter()
            .find(|s| s.subject == 0)
            .map(|s| (s.state.to_string(), s.detail.clone())),
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vmc_into_server_retargets_eases_on_loss_and_resumes() {
    // The sender: the procedural humanoid, whose bones carry HumanBodyBones names.
    let clip = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
    let names: Vec<String> = clip.skeleton.names().to_vec();
    let (server, to) = start_vmc_server(ServerConfig {
        rate_hz: RATE,
        // The output is compared with plain `Mapping::apply`: no foot lock on top (it is
        // judged in server/tests/foot_lock.rs).
        performers: vec![PerformerSpec {
            foot_lock: Some(false),
            ..PerformerSpec::target_file("builtin:mannequin")
        }],
        ..ServerConfig::default()
    })
    .await;
    let mut ws = connect(&server.stream_url()).await;
    let (hello, _) = handshake(&mut ws).await;
    let ServerMessage::Hello { subjects, .. } = hello else {
        unreachable!()
    };
    assert_eq!(subjects.len(), 2);
    assert_eq!(subjects[1].source, Some(0));
    assert_eq!(
        wait_json(&mut ws, Duration::from_secs(3), source_state)
            .await
            .as_deref(),
        Some("connecting")
    );

    // A sender thread: a moving pose for half a second, then one held pose until told to stop.
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sender = {
        let stop = stop.clone();
        let clip = clip.clone();
        let names = names.clone();
        std::thread::spawn(move || {
            let n = clip.poses.len();
            stream_clip(
                to,
                &clip,
                &names,
                |_| !stop.load(std::sync::atomic::Ordering::Relaxed),
                |k, elapsed| {
                    let moving = elapsed < Duration::from_millis(500);
                    if moving {
                        k % n
                    } else {
                        17
                    }
                },
            );
        })
    };
    let held = clip.poses[17].clone();

    // The source's learnt skeleton arrives as a new `skeleton` message, then the re-map.
    let mut source_skeleton = None;
    let mut target_skeleton = None;
    let mut mapping_entries = None;
    let mut last_source = None;
    let mut last_target = None;
    let t0 = Instant::now();
    // Read for 1.5 s: long past the moving part, so the latest frames show the held pose.
    while t0.elapsed() < Duration::from_millis(1500) {
        match next(&mut ws, Duration::from_secs(2)).await.unwrap() {
            Incoming::Json(ServerMessage::Skeleton { subject, bones, .. }) => {
                let sk = rigcast_server::skeleton_wire::skeleton_from_bones(&bones).unwrap();
                if subject == 0 {
                    source_skeleton = Some(sk);
                } else {
                    target_skeleton = Some(sk);
                }
            }
            Incoming::Json(ServerMessage::Mapping {
                subject: 1,
                entries,
                ..
            }) => mapping_entries = Some(entries),
            Incoming::Frame(f, _) if f.header.subject == 0 => last_source = Some(f),
            Incoming::Frame(f, _) if f.header.subject == 1 => last_target = Some(f),
            _ => {}
        }
    }
    let source_skeleton = Arc::new(source_skeleton.expect("the VMC sender's skeleton"));
    let target_skeleton = target_skeleton.unwrap_or_else(|| {
        // The handshake's skeleton message of the target was consumed by `handshake`.
        rigcast_engine::builtin::mannequin().unwrap()
    });
    let mapping_entries = mapping_entries.expect("a mapping message after the re-map");
    let source_frame = last_source.unwrap();
    let target_frame = last_target.unwrap();
    assert_eq!(source_skeleton.num_bones(), clip.skeleton.num_bones());

    // Expected: Mapping::apply on the same input.
    let table = auto_map(
        &SkeletonView::rest(&source_skeleton),
        &SkeletonView::rest(&target_skeleton),
        &MapOptions::default(),
    );
    for (e, t) in mapping_entries.iter().zip(target_skeleton.bone_ids()) {
        let expected = table
            .get(t)
            .and_then(|e| e.primary())
            .map(|r| source_skeleton.name(r.bone).to_string());
        assert_eq!(e.source, expected, "mapping of {}", e.target);
    }
    let mut mapping = Mapping::build(
        &[&source_skeleton],
        &target_skeleton,
        &table,
        &RetargetOptions {
            frame_time_secs: (1.0 / RATE) as f32,
            ..RetargetOptions::default()
        },
    )
    .unwrap();
    let mut input = source_skeleton.rest_pose();
    input.rotations.copy_from_slice(&source_frame.rotations);
    input.set_root_translation(source_frame.root);
    let mut expected = mapping.new_target_pose();
    mapping.apply_one(&input, &mut expected).unwrap();
    let err = max_angle(&expected.rotations, &target_frame.rotations);
    eprintln!("retargeted target vs Mapping::apply: {:.2e} rad", err);
    assert!(
        err < 2e-3,
        "target differs from Mapping::apply by {err} rad"
    );
    // And the source frame is the held pose.
    assert!(max_angle(&source_frame.rotations, &held.rotations) < 2e-3);

    // Stop sending: lost, and the target eases to its own rest pose (not the source's T-pose
    // retargeted: the mannequin's rest is an A-pose).
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    sender.join().unwrap();
    let rest = target_skeleton.rest_pose();
    assert!(
        max_angle(&rest.rotations, &mapping.aligned_rest_pose().rotations) > 0.2,
        "the character's rest and the aligned rest must differ for this check to mean anything"
    );
    let stopped = Instant::now();
    let mut steps = Vec::new();
    let mut to_rest = Vec::new();
    let mut prev: Option<(Vec<Quat>, u64)> = None;
    let mut saw_lost = false;
    let mut lost_detail = String::new();
    while stopped.elapsed() < Duration::from_millis(1300) {
        match next(&mut ws, Duration::from_secs(1)).await.unwrap() {
            Incoming::Json(m) => {
                if let Some((state, detail)) = source_record(&m) {
                    if state == "lost" {
                        saw_lost = true;
                        lost_detail = detail;
                    }
                }
            }
            Incoming::Frame(f, _) if f.header.subject == 1 => {
                // The ease follows the clock, so a tick the loaded machine ran late moves
                // further: judge each step per tick period actually elapsed (send times).
                if let Some((p, sent)) = &prev {
                    let ticks =
                        (f.header.send_nanos.saturating_sub(*sent) as f64 * 1e-9 * RATE).max(1.0);
                    steps.push(max_angle(p, &f.rotations) / ticks as f32);
                }
                to_rest.push(max_angle(&f.rotations, &rest.rotations));
                prev = Some((f.rotations, f.header.send_nanos));
            }
            _ => {}
        }
    }
    assert!(saw_lost, "no source_status with state lost");
    assert!(
        !lost_detail.is_empty(),
        "a lost source says why in its detail"
    );
    let status: serde_json::Value = {
        let (_, body) = http_get(server.local_addr(), "/v1/status").await;
        serde_json::from_str(&body).unwrap()
    };
    assert_eq!(status["subjects"][0]["source"]["state"], "lost");
    assert_eq!(status["subjects"][1]["kind"], "target");
    let biggest = steps.iter().copied().fold(0.0, f32::max);
    eprintln!(
        "ease-out: {} frames, biggest step {:.2}°, start {:.1}° from rest, end {:.3}°",
        to_rest.len(),
        biggest.to_degrees(),
        to_rest.first().unwrap().to_degrees(),
        to_rest.last().unwrap().to_degrees()
    );
    assert!(
        to_rest.first().unwrap().to_degrees() > 10.0,
        "the held pose is near rest"
    );
    // Smoothstep over 0.5 s peaks at 1.5× the mean step (start / 30 ticks at 60 Hz); allow
    // a tick of timer jitter on top, never a jump.
    let mean_step = to_rest.first().unwrap() / (0.5 * RATE as f32);
    assert!(
        biggest <= 2.0 * mean_step,
        "jump of {}°",
        biggest.to_degrees()
    );
    for w in to_rest.windows(2) {
        assert!(w[1] <= w[0] + 1e-3, "not monotonic: {} → {}", w[0], w[1]);
    }
    assert!(*to_rest.last().unwrap() < 2e-3, "did not reach rest");

    // Resume: live again, smoothly back to the retargeted pose.
    let resume = tokio::task::spawn_blocking(move || {
        let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut enc = VmcEncoder::new();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_millis(900) {
            rigcast_tests::send_vmc_pose(&sender, to, &mut enc, &names, &clip.poses[17], 10.0);
            std::thread::sleep(Duration::from_secs_f64(1.0 / RATE));
        }
    });
    let mut prev: Option<Vec<Quat>> = None;
    let mut biggest = 0.0f32;
    let mut last = None;
    let mut saw_live = false;
    let mut live_detail = None;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(800) {
        match next(&mut ws, Duration::from_secs(1)).await.unwrap() {
            Incoming::Json(m) => {
                if let Some((state, detail)) = source_record(&m) {
                    if state == "live" {
                        saw_live = true;
                        live_detail = Some(detail);
                    }
                }
            }
            Incoming::Frame(f, _) if f.header.subject == 1 => {
                if let Some(p) = &prev {
                    biggest = biggest.max(max_angle(p, &f.rotations));
                }
                prev = Some(f.rotations.clone());
                last = Some(f);
            }
            _ => {}
        }
    }
    resume.await.unwrap();
    assert!(saw_live, "no source_status with state live after resuming");
    assert_eq!(
        live_detail.as_deref(),
        Some(""),
        "the loss detail ({lost_detail:?}) must be cleared once the source is live again"
    );
    let (_, body) = http_get(server.local_addr(), "/v1/status").await;
    let status: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(status["subjects"][0]["source"]["detail"], "");
    // Easing in covers the whole way from rest back to the live pose over 0.2 s (12 ticks at
    // 60 Hz); ticks skipped on a loaded machine make single steps bigger, but a snap would
    // cover the whole distance in one step.
    let distance = max_angle(&rest.rotations, &expected.rotations);
    eprintln!(
        "ease-in: biggest step {:.2}° of {:.1}°",
        biggest.to_degrees(),
        distance.to_degrees()
    );
    assert!(
        biggest < 0.4 * distance,
        "jump of {}° on resume (of {}°)",
        biggest.to_degrees(),
        distance.to_degrees()
    );
    let err = max_angle(&expected.rotations, &last.unwrap().rotations);
    assert!(err < 2e-3, "after resuming the target is {err} rad off");
    server.shutdown().await;
}

/// `on_lost = hold`: while the source is lost the target keeps its last pose exactly, and the
/// source's detail is cleared once it is live again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hold_keeps_the_last_pose_while_the_source_is_lost() {
    let clip = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
    let names: Vec<String> = clip.skeleton.names().to_vec();
    let (server, to) = start_vmc_server(ServerConfig {
        rate_hz: RATE,
        performers: vec![PerformerSpec::target_file("builtin:mannequin")],
        on_lost: rigcast_engine::settings::OnLost::Hold,
        ..ServerConfig::default()
    })
    .await;
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    let send_for = |millis: u64, moving: bool| {
        let (clip, names) = (clip.clone(), names.clone());
        tokio::task::spawn_blocking(move || {
            let n = clip.poses.len();
            stream_clip(
                to,
                &clip,
                &names,
                |elapsed| elapsed < Duration::from_millis(millis),
                |k, _| if moving { k % n } else { 17 },
            );
        })
    };
    send_for(800, true).await.unwrap();
    // The last live frame of the target, then everything while lost.
    let stopped = Instant::now();
    let mut last_live: Option<Vec<Quat>> = None;
    let mut while_lost: Vec<Vec<Quat>> = Vec::new();
    let mut lost = false;
    while stopped.elapsed() < Duration::from_millis(1500) {
        match next(&mut ws, Duration::from_secs(1)).await.unwrap() {
            Incoming::Json(m) => lost |= source_state(&m).as_deref() == Some("lost"),
            Incoming::Frame(f, _) if f.header.subject == 1 => {
                if lost {
                    while_lost.push(f.rotations);
                } else {
                    last_live = Some(f.rotations);
                }
            }
            _ => {}
        }
    }
    assert!(lost, "the source never turned lost");
    let last_live = last_live.expect("target frames before the loss");
    assert!(
        while_lost.len() >= 10,
        "only {} frames while lost",
        while_lost.len()
    );
    let worst = while_lost
        .iter()
        .map(|r| max_angle(r, &last_live))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "the held pose drifted by {worst} rad");
    let moved_from_rest = max_angle(
        &last_live,
        &rigcast_engine::builtin::mannequin()
            .unwrap()
            .rest_pose()
            .rotations,
    );
    assert!(
        moved_from_rest > 0.1,
        "the held pose is the rest pose: nothing was checked"
    );
    let resume = send_for(1200, false);
    let detail = wait_json(&mut ws, Duration::from_secs(3), |m| {
        source_record(m)
            .filter(|(state, _)| state == "live")
            .map(|(_, d)| d)
    })
    .await;
    resume.await.unwrap();
    assert_eq!(
        detail.as_deref(),
        Some(""),
        "detail not cleared on recovery"
    );
    server.shutdown().await;
}
