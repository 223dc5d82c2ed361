//! `rigcast calibrate` end to end: an in-process server reads a serial IMU suit from a real
//! pseudo-terminal (behind a symlink named in the suit's TOML config), the performer's sensors
//! are strapped on at arbitrary angles, and the real binary calibrates it.
//!
//! Independent answers: the sensors report `bone world rotation · mounting offset`, so before
//! calibration the streamed locals are the offsets' (visibly off), after a T-pose calibration
//! the same readings stream as the rest pose, and a known sensor turn `d` gives local `d` on
//! its bone (and `d⁻¹` on the unturned child). The N-pose is checked the same way against
//! `n_pose`. Replay subjects and sources without data are refused with non-zero exits.
#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::os::unix::io::RawFd;
use std::process::Output;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use glam::{Quat, Vec3};
use rigcast_protocol::frame::decode_frame;
use rigcast_retarget::{world_transforms, Skeleton};
use rigcast_server::{ServerConfig, SourceSpec};
use rigcast_sources::live::humanoid::{default_humanoid, n_pose};
use tokio_tungstenite::tungstenite::Message;

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

#[path = "../../sources/tests/common/pty.rs"]
mod pty;
use pty::{angle, Pty};

/// The performer: re-sends the current sensor readings (CSV `id,w,x,y,z`) every 20 ms, as a
/// suit streams continuously.
struct Performer {
    readings: Arc<Mutex<Vec<(u32, Quat)>>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Performer {
    fn start(master: RawFd) -> Performer {
        let readings: Arc<Mutex<Vec<(u32, Quat)>>> = Arc::default();
        let stop = Arc::new(AtomicBool::new(false));
        let (r, s) = (readings.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                let mut text = String::new();
                for (id, q) in r.lock().unwrap().iter() {
                    text.push_str(&format!("{id},{},{},{},{}\r\n", q.w, q.x, q.y, q.z));
                }
                let mut rest = text.as_bytes();
                while !rest.is_empty() {
                    match nix::unistd::write(master, rest) {
                        Ok(n) => rest = &rest[n..],
                        Err(_) => break,
                    }
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        Performer {
            readings,
            stop,
            thread: Some(thread),
        }
    }

    fn hold(&self, readings: Vec<(u32, Quat)>) {
        *self.readings.lock().unwrap() = readings;
    }
}

impl Drop for Performer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

const SENSORS: [(u32, &str); 3] = [(0, "Hips"), (1, "LeftUpperArm"), (2, "LeftLowerArm")];

/// Runs `rigcast calibrate ARGS` (blocking, off the runtime's worker).
async fn calibrate(args: &[&str]) -> Output {
    let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
    tokio::task::spawn_blocking(move || {
        // An empty config folder: the token comes from the arguments, never the user's file.
        let config_home =
            std::env::temp_dir().join(format!("rigcast-calibrate-xdg-{}", std::process::id()));
        std::process::Command::new(env!("CARGO_BIN_EXE_rigcast"))
            .arg("calibrate")
            .args(&args)
            .env("XDG_CONFIG_HOME", config_home)
            .output()
            .unwrap()
    })
    .await
    .unwrap()
}

/// Runs `rigcast calibrate ARGS`, which must fail with every one of `needles` in its stderr.
async fn refused(args: &[&str], needles: &[&str]) {
    let out = calibrate(args).await;
    let err = text(&out.stderr);
    assert!(
        !out.status.success(),
        "{args:?} succeeded: {}",
        text(&out.stdout)
    );
    for n in needles {
        assert!(err.contains(n), "{args:?}: no {n:?} in {err}");
    }
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Reads frames of subject 0 until `pred(rotations)` holds; panics with the last frame after
/// `secs`.
async fn wait_pose(ws: &mut Ws, secs: f32, what: &str, pred: impl Fn(&[Quat]) -> bool) {
    let deadline = Instant::now() + Duration::from_secs_f32(secs);
    let mut last = Vec::new();
    while Instant::now() < deadline {
        let msg = tokio::time::timeout(Duration::from_secs(1), ws.next()).await;
        let Ok(Some(Ok(Message::Binary(b)))) = msg else {
            continue;
        };
        let f = decode_frame(&b).unwrap();
        if f.header.subject != 0 {
            continue;
        }
        if pred(&f.rotations) {
            return;
        }
        last = f.rotations;
    }
    panic!("timed out waiting for {what}; last streamed rotations {last:?}");
}

/// `GET /v1/status` → JSON.
fn status(addr: std::net::SocketAddr) -> serde_json::Value {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    write!(
        s,
        "GET /v1/status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut body = String::new();
    s.read_to_string(&mut body).unwrap();
    let json = &body[body.find("\r\n\r\n").unwrap() + 4..];
    serde_json::from_str(json).unwrap()
}

/// Max angle between the streamed locals and `expected` over the sensor bones and Spine.
fn error_vs(sk: &Skeleton, rot: &[Quat], expected: impl Fn(&str) -> Quat) -> f32 {
    ["Hips", "Spine", "LeftUpperArm", "LeftLowerArm"]
        .iter()
        .map(|b| angle(rot[sk.bone(b).unwrap().index()], expected(b)))
        .fold(0.0, f32::max)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calibrate_command_removes_mounting_offsets() {
    let dir = std::env::temp_dir().join(format!("rigcast-calibrate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("imu");
    let pty = Pty::new();
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&pty.path, &link).unwrap();
    let config = dir.join("suit.toml");
    let mut toml = format!(
        "path = {:?}\nformat = \"csv\"\nreconnect_secs = 0.1\nlost_after_secs = 1.0\n",
        link.to_str().unwrap()
    );
    for (sensor, bone) in SENSORS {
        toml.push_str(&format!(
            "[[sensors]]\nsensor = {sensor}\nbone = {bone:?}\n"
        ));
    }
    std::fs::write(&config, toml).unwrap();

    let handle = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![
            SourceSpec::Serial(rigcast_server::config::SerialSpec {
                config: config.clone(),
                name: None,
            }),
            SourceSpec::demo(),
        ],
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    // Calibrating changes the server: every request below carries the control token.
    let url = handle.control_stream_url();
    let addr = handle.local_addr();
    let sk = default_humanoid().unwrap();
    let (mut ws, _) = tokio_tungstenite::connect_async(&url).await.unwrap();

    // The request itself: refusals name the problem with a code.
    for (request, code) in [
        (r#"{"type":"calibrate","subject":99}"#, "unknown_subject"),
        (
            r#"{"type":"calibrate","subject":1,"pose":"t"}"#,
            "not_calibratable",
        ),
        (
            r#"{"type":"calibrate","subject":0,"delay_secs":61}"#,
            "invalid_fields",
        ),
        (
            r#"{"type":"calibrate","subject":0,"pose":"x"}"#,
            "invalid_fields",
        ),
    ] {
        use futures_util::SinkExt;
        ws.send(Message::text(request)).await.unwrap();
        let reply = loop {
            let m = tokio::time::timeout(Duration::from_secs(5), ws.next())
                .await
                .unwrap()
                .unwrap()
                .unwrap();
            if let Message::Text(t) = m {
                let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                if v["type"] == "error" || v["type"] == "ack" {
                    break v;
                }
            }
        };
        assert_eq!(reply["code"], code, "{request} → {reply}");
    }

    // Without the token the request is refused, naming the remedy.
    let plain = handle.stream_url();
    refused(
        &["--url", &plain, "--delay", "0"],
        &["unauthorized", "token"],
    )
    .await;
    // No sensor data yet: the source is not live, so there is nothing to capture.
    refused(
        &["--url", &url, "--delay", "0"],
        &["calibration failed", "suit"],
    )
    .await;
    // A replay subject is not calibratable: refused at once, non-zero exit.
    let demo = ["--url", &url, "--subject", "demo", "--delay", "0"];
    refused(&demo, &["not_calibratable", "replay source"]).await;
    // So is a subject that does not exist (refused by the CLI, naming the choices).
    refused(&["--url", &url, "--subject", "9"], &["0 \"suit\" (serial)"]).await;

    // The performer holds the T-pose (the humanoid's rest: identity world rotations) with
    // sensors strapped on at arbitrary angles: they read their mounting offsets.
    let mount = [
        Quat::from_rotation_x(1.0),
        Quat::from_euler(glam::EulerRot::XYZ, 0.3, -0.8, 2.0),
        Quat::from_rotation_z(2.5),
    ];
    let performer = Performer::start(pty.master);
    performer.hold(vec![(0, mount[0]), (1, mount[1]), (2, mount[2])]);
    // Uncalibrated, the streamed pose follows the offsets, so it is far from the rest pose.
    let uncalibrated = |b: &str| match b {
        "Hips" => mount[0],
        "LeftUpperArm" => mount[0].inverse() * mount[1],
        "LeftLowerArm" => mount[1].inverse() * mount[2],
        _ => Quat::IDENTITY,
    };
    let sk2 = sk.clone();
    wait_pose(&mut ws, 5.0, "the uncalibrated pose", move |r| {
        error_vs(&sk2, r, uncalibrated) < 1e-3
    })
    .await;
    // …which is visibly off the rest pose the performer actually holds.
    let off: Vec<Quat> = sk.names().iter().map(|b| uncalibrated(b)).collect();
    assert!(error_vs(&sk, &off, |_| Quat::IDENTITY) > 0.9);

    // The real binary: countdown, request, outcome.
    let started = Instant::now();
    let out = calibrate(&["--url", &url, "--pose", "t", "--delay", "1"]).await;
    let stdout = text(&out.stdout);
    assert!(
        out.status.success(),
        "stdout {stdout}\nstderr {}",
        text(&out.stderr)
    );
    assert!(started.elapsed() >= Duration::from_secs(1), "no delay");
    assert!(
        stdout.contains("hold a T-pose") && stdout.contains(" 1"),
        "{stdout}"
    );
    assert!(stdout.contains("calibrated (T-pose)"), "{stdout}");
    eprintln!("rigcast calibrate printed:\n{stdout}");

    // The same readings now stream as the rest pose.
    let sk2 = sk.clone();
    wait_pose(&mut ws, 5.0, "the rest pose after calibration", move |r| {
        error_vs(&sk2, r, |_| Quat::IDENTITY) < 1e-3
    })
    .await;
    // A known turn of the upper arm's sensor (arm lowered 60° and twisted): the upper arm
    // turns by exactly that, its unturned child counter-rotates.
    let d = Quat::from_rotation_z(-60f32.to_radians()) * Quat::from_rotation_x(0.3);
    performer.hold(vec![(0, mount[0]), (1, d * mount[1]), (2, mount[2])]);
    let sk2 = sk.clone();
    wait_pose(&mut ws, 5.0, "the turned upper arm", move |r| {
        error_vs(&sk2, r, |b| match b {
            "LeftUpperArm" => d,
            "LeftLowerArm" => d.inverse(),
            _ => Quat::IDENTITY,
        }) < 1e-3
    })
    .await;
    // The outcome is in /v1/status too.
    let st = tokio::task::spawn_blocking(move || status(addr))
        .await
        .unwrap();
    let suit = st["subjects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == "suit")
        .unwrap();
    assert_eq!(suit["source"]["detail"], "calibrated (T-pose)", "{suit}");
    assert_eq!(suit["source"]["kind"], "serial");

    // N-pose: the performer now holds the arms down; sensors read (N-pose world) · offset.
    let n = n_pose(&sk);
    let nw = world_transforms(&sk, &n);
    let world_of = |b: &str| nw[sk.bone(b).unwrap().index()].rotation;
    performer.hold(
        SENSORS
            .iter()
            .zip(mount)
            .map(|((id, bone), m)| (*id, world_of(bone) * m))
            .collect(),
    );
    let out = calibrate(&[
        "--url",
        &url,
        "--subject",
        "suit",
        "--pose",
        "n",
        "--delay",
        "0.3",
    ])
    .await;
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    assert!(stdout.contains("calibrated (N-pose)"), "{stdout}");
    let (sk2, n2) = (sk.clone(), n.clone());
    wait_pose(&mut ws, 5.0, "the N-pose after N calibration", move |r| {
        error_vs(&sk2, r, |b| n2.rotations[sk2.bone(b).unwrap().index()]) < 1e-3
    })
    .await;
    // Back to a T-pose: the arm sensors turn by the inverse of the N-pose swing.
    performer.hold(vec![(0, mount[0]), (1, mount[1]), (2, mount[2])]);
    let sk2 = sk.clone();
    wait_pose(&mut ws, 5.0, "the T-pose after N calibration", move |r| {
        error_vs(&sk2, r, |_| Quat::IDENTITY) < 1e-3
    })
    .await;
    // Check the N-pose is a real N-pose (upper arm hanging down), not a vacuous one.
    let arm = sk.bone("LeftUpperArm").unwrap().index();
    let elbow = sk.bone("LeftLowerArm").unwrap().index();
    let arm_dir = (nw[elbow].translation - nw[arm].translation).normalize_or_zero();
    assert!(arm_dir.angle_between(Vec3::NEG_Y) < 5f32.to_radians());

    drop(performer);
    drop(ws);
    handle.shutdown().await;
    let _ = std::fs::remove_dir_all(&dir);
}
