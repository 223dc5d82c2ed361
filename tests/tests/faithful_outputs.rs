//! The motion that leaves the server is the character's motion, judged by programs that share
//! no code with rigcast:
//! - VMC: python-osc (PyPI) receives the demo's VMC output and applies the local rotations, as
//!   VMC receivers do, onto a +Z-facing Unity T-pose humanoid with its own forward kinematics
//!   (`tests/scripts/vmc_avatar.py`): knees bend backwards, elbows forwards, the left leg is on
//!   the avatar's left, it faces where the character faces, and its hips are as high as the
//!   character's.
//! - WebSocket v2: this test's own FK of a version 2 frame puts the mannequin's pelvis exactly
//!   where the server's FK (the VMC `Hips`, a world transform) puts it in the same tick, and
//!   the pelvis really moves; a version 1 client on the same server still decodes every frame.
//! - Same tick: the VMC bundle and the WebSocket frame of one pose leave in the same tick.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rigcast_protocol::coords::{internal_from_unity_position, internal_from_unity_rotation};
use rigcast_protocol::frame::DecodedFrame;
use rigcast_protocol::vmc::{decode_packet, VmcMessage};
use rigcast_protocol::ServerMessage;
use rigcast_tests::*;
use serde_json::Value;

/// The skeleton of a `skeleton` message, with FK of a decoded frame of either version.
struct Wire {
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    rest_t: Vec<Vec3>,
    slots: Vec<Option<usize>>,
}

impl Wire {
    fn new(message: &ServerMessage) -> Wire {
        let ServerMessage::Skeleton { bones, .. } = message else {
            panic!("not a skeleton: {message:?}")
        };
        let mut next = 0;
        Wire {
            names: bones.iter().map(|b| b.name.clone()).collect(),
            parents: bones.iter().map(|b| b.parent.map(|p| p as usize)).collect(),
            rest_t: bones
                .iter()
                .map(|b| Vec3::from_array(b.rest_translation))
                .collect(),
            slots: bones
                .iter()
                .map(|b| {
                    b.translated.then(|| {
                        next += 1;
                        next - 1
                    })
                })
                .collect(),
        }
    }

    fn bone(&self, name: &str) -> usize {
        self.names.iter().position(|n| n == name).unwrap()
    }

    /// World (rotation, position) of every bone.
    fn fk(&self, f: &DecodedFrame) -> Vec<(Quat, Vec3)> {
        let mut out: Vec<(Quat, Vec3)> = Vec::with_capacity(self.names.len());
        for i in 0..self.names.len() {
            let t = match (f.version, self.slots[i]) {
                (2, Some(k)) => f.translations[k],
                (1, _) if i == 0 => f.root,
                _ => self.rest_t[i],
            };
            let r = f.rotations[i];
            out.push(match self.parents[i] {
                None => (r, t),
                Some(p) => (out[p].0 * r, out[p].1 + out[p].0 * t),
            });
        }
        out
    }
}

/// Connects, reads hello and skeletons, and switches to `version` when it is not 1.
async fn client(url: &str, version: u16) -> (Ws, Vec<ServerMessage>) {
    let mut ws = connect(url).await;
    let (hello, skeletons) = handshake(&mut ws).await;
    let ServerMessage::Hello {
        protocol_version,
        protocol_versions,
        ..
    } = hello
    else {
        unreachable!()
    };
    assert_eq!(protocol_version, 1, "sessions start in version 1");
    assert_eq!(protocol_versions, [1, 2]);
    if version != 1 {
        send_text(
            &mut ws,
            &format!(r#"{{"type":"set_protocol","version":{version}}}"#),
        )
        .await;
        loop {
            match next_json(&mut ws, Duration::from_secs(5)).await {
                Some(ServerMessage::Protocol { version: v }) => {
                    assert_eq!(v, version);
                    break;
                }
                Some(_) => {}
                None => panic!("no protocol answer"),
            }
        }
    }
    (ws, skeletons)
}

/// One VMC tick: bone name → (position, rotation) in internal space, and its arrival time.
type VmcTick = (HashMap<String, (Vec3, Quat)>, Instant);

async fn collect_vmc(udp: tokio::net::UdpSocket, duration: Duration) -> Vec<VmcTick> {
    let mut buf = vec![0u8; 65536];
    let mut ticks: Vec<VmcTick> = Vec::new();
    let deadline = Instant::now() + duration;
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        let Ok(Ok(n)) = tokio::time::timeout(left, udp.recv(&mut buf)).await else {
            break;
        };
        let now = Instant::now();
        for m in decode_packet(&buf[..n]).unwrap() {
            match m.unwrap() {
                VmcMessage::Time { .. } => ticks.push((HashMap::new(), now)),
                VmcMessage::BonePos {
                    name,
                    position,
                    rotation,
                } => {
                    if let Some((bones, _)) = ticks.last_mut() {
                        bones.insert(
                            name,
                            (
                                internal_from_unity_position(position),
                                internal_from_unity_rotation(rotation),
                            ),
                        );
                    }
                }
                _ => {}
            }
        }
    }
    ticks.pop(); // the deadline may cut the last one short
    ticks
}

/// Frames of `subject` with their arrival time.
async fn collect_subject(
    ws: &mut Ws,
    subject: u32,
    duration: Duration,
) -> Vec<(DecodedFrame, Instant)> {
    let deadline = Instant::now() + duration;
    let mut out = Vec::new();
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match next(ws, left).await {
            Some(Incoming::Frame(f, _)) if f.header.subject == subject => {
                out.push((f, Instant::now()))
            }
            Some(_) => {}
            None => break,
        }
    }
    out
}

fn target_id(skeletons: &[ServerMessage]) -> (u32, Wire) {
    for s in skeletons {
        if let ServerMessage::Skeleton { subject, name, .. } = s {
            if name == "mannequin" {
                return (*subject, Wire::new(s));
            }
        }
    }
    panic!("the demo streams no mannequin")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn websocket_v2_pelvis_matches_server_fk_in_the_same_tick_and_v1_still_decodes() {
    let udp = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let config = rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        vmc_out: vec![rigcast_server::VmcOut::to(
            udp.local_addr().unwrap().to_string(),
        )],
        ..rigcast_server::ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let (mut v2, skeletons) = client(&server.stream_url(), 2).await;
    let (mut v1, _) = client(&server.stream_url(), 1).await;
    let (id, wire) = target_id(&skeletons);
    let pelvis = wire.bone("pelvis");
    assert!(
        wire.slots[pelvis].is_some(),
        "the pelvis is not marked translated"
    );
    let span = Duration::from_millis(2500);
    let (vmc, frames2, frames1) = tokio::join!(
        collect_vmc(udp, span),
        collect_subject(&mut v2, id, span),
        collect_subject(&mut v1, id, span),
    );
    server.shutdown().await;
    assert!(vmc.len() >= 60, "only {} VMC ticks", vmc.len());
    assert!(frames2.len() >= 60, "only {} v2 frames", frames2.len());
    assert!(frames1.len() >= 60, "only {} v1 frames", frames1.len());

    // v1 still decodes and carries the same rotations as v2 for the same seq.
    let by_seq: HashMap<u64, &DecodedFrame> =
        frames2.iter().map(|(f, _)| (f.header.seq, f)).collect();
    let mut same_seq = 0;
    for (f, _) in &frames1 {
        assert_eq!(f.version, 1);
        if let Some(g) = by_seq.get(&f.header.seq) {
            assert_eq!(f.rotations, g.rotations, "seq {}", f.header.seq);
            same_seq += 1;
        }
    }
    assert!(same_seq >= 30, "only {same_seq} seqs seen by both clients");

    // Pair each VMC tick with the v2 frame of the same pose (pelvis world rotation), then
    // compare the pelvis height and the arrival times.
    // A pose repeats while the source has no new frame (same seq, same VMC pose): compare
    // first arrivals only, or a repeat would pair with the wrong tick.
    let mut seen = std::collections::HashSet::new();
    let worlds: Vec<(Quat, Vec3, Instant)> = frames2
        .iter()
        .filter(|(f, _)| seen.insert(f.header.seq))
        .map(|(f, t)| {
            let w = wire.fk(f)[pelvis];
            (w.0, w.1, *t)
        })
        .collect();
    let mut previous: Option<Quat> = None;
    let vmc: Vec<&VmcTick> = vmc
        .iter()
        .filter(|(bones, _)| {
            let q = bones.get("Hips").map(|b| b.1);
            let repeat = matches!((q, previous), (Some(a), Some(b)) if rotation_angle(a, b) < 1e-6);
            previous = q;
            !repeat
        })
        .collect();
    let (mut worst_mm, mut paired) = (0.0f32, 0);
    let mut lags_ms: Vec<f64> = Vec::new();
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for (bones, at) in vmc.iter().copied() {
        let Some(&(hips_p, hips_q)) = bones.get("Hips") else {
            continue;
        };
        // The looping demo shows the same pose again every loop: of the frames with exactly
        // this pose, the one that arrived nearest (a lagging WebSocket would still be a tick
        // late: the pose recurs only a loop later).
        let gap = |t: Instant| if t >= *at { t - *at } else { *at - t };
        let Some(best) = worlds
            .iter()
            .filter(|w| rotation_angle(w.0, hips_q) <= 1e-4)
            .min_by_key(|w| gap(w.2))
        else {
            continue; // our client joined later or left earlier than this tick
        };
        paired += 1;
        worst_mm = worst_mm.max((best.1.y - hips_p.y).abs() * 1000.0);
        lo = lo.min(best.1.y);
        hi = hi.max(best.1.y);
        let lag = if best.2 >= *at {
            (best.2 - *at).as_secs_f64()
        } else {
            -(*at - best.2).as_secs_f64()
        };
        lags_ms.push(lag * 1000.0);
    }
    lags_ms.sort_by(f64::total_cmp);
    let median_lag = lags_ms.get(lags_ms.len() / 2).copied().unwrap_or(f64::NAN);
    println!(
        "{paired} VMC ticks paired; pelvis height error ≤ {worst_mm:.4} mm over a {:.1} mm range; \
         WebSocket arrival − VMC arrival median {median_lag:.2} ms",
        (hi - lo) * 1000.0
    );
    assert!(paired >= 30, "only {paired} VMC poses match a v2 frame");
    assert!(
        worst_mm < 1.0,
        "pelvis height differs from server FK by {worst_mm} mm"
    );
    assert!(hi - lo > 0.01, "the pelvis does not bob ({} m)", hi - lo);
    // One tick at 60 Hz is 16.7 ms; the same tick's outputs arrive well within half of it.
    assert!(
        median_lag.abs() < 8.0,
        "the WebSocket frame of a pose arrives {median_lag:.1} ms after its VMC bundle"
    );
}

/// The venv `scripts/setup-vmc-check.sh` makes, or None (skip) with RIGCAST_SKIP_APPS=1.
fn vmc_check_python() -> Option<PathBuf> {
    let home = std::env::var_os("RIGCAST_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/rigcast")))
        .unwrap();
    let python = home.join("vmc-check/venv/bin/python");
    if python.is_file() {
        return Some(python);
    }
    if std::env::var("RIGCAST_SKIP_APPS").as_deref() == Ok("1") {
        eprintln!("SKIP: {} missing and RIGCAST_SKIP_APPS=1", python.display());
        return None;
    }
    panic!(
        "{} missing: run scripts/setup-vmc-check.sh",
        python.display()
    );
}

/// The bend at joint `b` between segments `a→b` and `b→c`, from world positions: what the
/// avatar shows must be the character's geometry, whatever axes its bones use.
fn bend(wire: &Wire, world: &[(Quat, Vec3)], a: &str, b: &str, c: &str) -> f32 {
    let p = |n: &str| world[wire.bone(n)].1;
    (p(b) - p(a)).angle_between(p(c) - p(b)).to_degrees()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vmc_output_poses_an_independent_z_facing_avatar() {
    let Some(python) = vmc_check_python() else {
        return;
    };
    let script = repo_root().join("tests/scripts/vmc_avatar.py");
    let mut child = Command::new(&python)
        .arg(&script)
        .arg("4")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let _guard_pid = child.id();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    let port: u16 = first.strip_prefix("PORT ").unwrap().parse().unwrap();
    let config = rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        vmc_out: vec![rigcast_server::VmcOut::to(format!("127.0.0.1:{port}"))],
        ..rigcast_server::ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let (mut ws, skeletons) = client(&server.stream_url(), 2).await;
    let (id, wire) = target_id(&skeletons);
    let frames = collect_subject(&mut ws, id, Duration::from_millis(3000)).await;
    let report = tokio::task::spawn_blocking(move || {
        let line = lines.next().unwrap().unwrap();
        let _ = child.wait();
        line
    })
    .await
    .unwrap();
    server.shutdown().await;
    let report: Value = serde_json::from_str(&report).unwrap();
    let ticks = report["ticks"].as_array().unwrap();
    assert!(
        ticks.len() >= 60,
        "the avatar received only {} ticks",
        ticks.len()
    );

    // The character itself, from the WebSocket (internal space).
    let pelvis = wire.bone("pelvis");
    let mut heights = Vec::new();
    let mut facing = Vec3::ZERO;
    let mut knee_max: f32 = 0.0;
    for (f, _) in &frames {
        let world = wire.fk(f);
        heights.push(world[pelvis].1.y);
        facing += world[pelvis].0 * Vec3::Z;
        knee_max = knee_max.max(bend(&wire, &world, "thigh_l", "calf_l", "foot_l"));
    }
    let f = |v: &Value| v.as_f64().unwrap() as f32;
    let avatar_heights: Vec<f32> = ticks.iter().map(|t| f(&t["hips_y"])).collect();
    let stats = |v: &[f32]| {
        (
            v.iter().cloned().fold(f32::MAX, f32::min),
            v.iter().sum::<f32>() / v.len() as f32,
            v.iter().cloned().fold(f32::MIN, f32::max),
        )
    };
    let (c, a) = (stats(&heights), stats(&avatar_heights));
    println!("hips height (min, mean, max): character {c:?}, avatar {a:?}");
    for (x, y, what) in [
        (c.0, a.0, "lowest"),
        (c.1, a.1, "mean"),
        (c.2, a.2, "highest"),
    ] {
        assert!(
            (x - y).abs() < 0.01,
            "{what} hips height: character {x} m, avatar {y} m"
        );
    }

    // Facing: the character's forward, mirrored into Unity, is the avatar's forward.
    let mut avatar_facing = Vec3::ZERO;
    for t in ticks {
        avatar_facing += Vec3::new(f(&t["facing"][0]), 0.0, f(&t["facing"][1]));
    }
    let expected = Vec3::new(-facing.x, 0.0, facing.z);
    let off = avatar_facing.angle_between(expected).to_degrees();
    println!("facing: character (internal) {facing:?}, avatar (Unity) {avatar_facing:?}, off by {off:.2}°");
    assert!(off < 5.0, "the avatar faces {off}° away from the character");
    assert!(
        avatar_facing.z > 0.0 && facing.z > 0.0,
        "the character faces +Z and so must the avatar"
    );

    // Bends: knees backwards, elbows forwards, whenever the joint is visibly bent.
    let mut avatar_knee_max: f32 = 0.0;
    for (joint, forward) in [("Knee", false), ("Elbow", true)] {
        for side in ["Left", "Right"] {
            let key = format!("{side}{joint}");
            let bent: Vec<(f32, f32)> = ticks
                .iter()
                .map(|t| (f(&t[&key][0]), f(&t[&key][1])))
                .filter(|(flex, _)| *flex > 5.0)
                .collect();
            let right_way = bent
                .iter()
                .filter(|(_, along)| (*along > 0.0) == forward)
                .count();
            println!(
                "{key}: bent > 5° in {} of {} ticks, the right way in {right_way}",
                bent.len(),
                ticks.len()
            );
            assert!(
                bent.len() >= 20,
                "{key} hardly bends: the check would be empty"
            );
            assert!(
                right_way as f32 >= 0.95 * bent.len() as f32,
                "{key} bends the wrong way in {} of {} ticks",
                bent.len() - right_way,
                bent.len()
            );
            if joint == "Knee" && side == "Left" {
                avatar_knee_max = bent.iter().map(|b| b.0).fold(0.0, f32::max);
            }
        }
    }
    println!("left knee flexion max: character {knee_max:.1}°, avatar {avatar_knee_max:.1}°");
    assert!(
        (knee_max - avatar_knee_max).abs() < 0.5,
        "the avatar's knee bends {avatar_knee_max}° at most, the character's {knee_max}°"
    );

    // Sides: the left foot is on the avatar's left (Unity -X of its hips frame).
    let mean = |key: &str| ticks.iter().map(|t| f(&t[key])).sum::<f32>() / ticks.len() as f32;
    let (left, right) = (mean("LeftFootSide"), mean("RightFootSide"));
    println!("feet across the hips: left {left:.3} m, right {right:.3} m");
    assert!(
        left < -0.03 && right > 0.03,
        "feet on the wrong sides: {left}, {right}"
    );
}
