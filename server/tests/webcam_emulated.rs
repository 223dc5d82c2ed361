//! `rigcast serve --source webcam:0?...` and `rigcast devices` through the real binary and the
//! real nokhwa -> V4L2 path, against the emulated camera (`sources/tests/v4l2_emu`, preloaded)
//! serving real footage: the chosen mode, model and stage latencies in `/v1/status` (the
//! camera's stages on its subject, the target's from the tick to the wire, consistent with
//! what a WebSocket client measures from the frames it receives), a second server
//! told the camera is busy, the camera unplugged mid-stream (the subject goes `lost`) and
//! plugged back (it comes back `live`), and `rigcast devices` listing it. Skipped with a printed
//! reason without the vision models, gcc, ffmpeg or the footage.
#![cfg(feature = "webcam")]
#![allow(clippy::unwrap_used)]

#[path = "../../sources/tests/v4l2_emu/mod.rs"]
mod v4l2_emu;

use std::io::{Read, Write};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rigcast_sources::vision::VisionAssets;
use serde_json::Value;
use v4l2_emu::{mode, EmuCamera};

struct Server {
    child: Child,
    port: u16,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn rigcast(cam: &EmuCamera, home: &std::path::Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rigcast"));
    cmd.env("XDG_CONFIG_HOME", home)
        .env("XDG_CACHE_HOME", home.join("cache"));
    for (k, v) in cam.env() {
        cmd.env(k, v);
    }
    cmd
}

fn serve(cam: &EmuCamera, home: &std::path::Path, source: &str) -> Server {
    let port = free_port();
    let child = rigcast(cam, home)
        .args(["serve", "--no-mapping-cache", "--listen"])
        .arg(format!("127.0.0.1:{port}"))
        .args(["--source", source, "--target", "builtin:mannequin"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    Server { child, port }
}

/// `GET /v1/status`, or None while the server is not answering yet.
fn status(port: u16) -> Option<Value> {
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    write!(s, "GET /v1/status HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n").ok()?;
    let mut body = String::new();
    s.read_to_string(&mut body).ok()?;
    let json = body.split_once("\r\n\r\n")?.1;
    serde_json::from_str(json).ok()
}

/// The source health of subject `name`.
fn health(port: u16, name: &str) -> Option<Value> {
    let st = status(port)?;
    st["subjects"]
        .as_array()?
        .iter()
        .find(|s| s["name"] == name)
        .map(|s| s["source"].clone())
}

/// Waits up to `secs` for `pred` on the subject's health; returns the last health seen.
fn wait_for(port: u16, name: &str, secs: u64, what: &str, pred: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    let mut last = Value::Null;
    while start.elapsed() < Duration::from_secs(secs) {
        if let Some(h) = health(port, name) {
            if pred(&h) {
                return h;
            }
            last = h;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("{name} never became {what} within {secs} s; last: {last}");
}

/// A WebSocket client (`rigcast loadtest`, its own process) reads the stream for a few
/// seconds; the target's `latency` in `/v1/status` then has every stage, and the camera
/// subject's `glass_to_wire` (capture to the server's write) agrees with the client's capture
/// to arrival of the same frames (the client counts from its first frame): a write comes
/// before its arrival, so the server's median cannot be later than the client's slowest. (The camera subject's frames are all camera
/// frames; a target's include the poses it falls back to while the person is out of view,
/// stamped when made, which a client cannot tell apart.)
fn wire_latency_matches_a_client(cam: &EmuCamera, home: &std::path::Path, port: u16) {
    let out = rigcast(cam, home)
        .args([
            "loadtest",
            "--clients",
            "1",
            "--secs",
            "3",
            // Count from the first frame written, as the server's status does: frames of a
            // warm-up the client skipped would be in the server's figures only.
            "--warm-up",
            "0",
            "--json",
            "--url",
        ])
        .arg(format!("ws://127.0.0.1:{port}/v1/stream"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    let st = status(port).unwrap();
    let subject = |kind: &str| {
        st["subjects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["kind"] == kind)
            .unwrap_or_else(|| panic!("no {kind} in {st}"))
            .clone()
    };
    let stage = |s: &Value, name: &str| {
        s["latency"]
            .as_array()
            .and_then(|l| l.iter().find(|x| x["stage"] == name))
            .unwrap_or_else(|| panic!("no {name} stage in {s}"))
            .clone()
    };
    let target = subject("target");
    for name in ["handoff", "retarget", "send", "glass_to_wire"] {
        assert!(
            stage(&target, name)["samples"].as_u64().unwrap() > 0,
            "{target}"
        );
    }
    let camera = subject("source");
    let client = report["glass_us"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["subject"] == camera["id"])
        .unwrap_or_else(|| panic!("the client saw no camera frame: {report}"));
    assert!(client["frames"].as_u64().unwrap() > 0, "{report}");
    let client_p99_ms = client["latency"]["p99"].as_f64().unwrap() / 1000.0;
    let server_p50_ms = stage(&camera, "glass_to_wire")["p50_ms"].as_f64().unwrap();
    assert!(
        server_p50_ms <= client_p99_ms + 5.0,
        "server glass_to_wire p50 {server_p50_ms} ms, client capture to arrival p99 {client_p99_ms} ms"
    );
    println!(
        "target latency: {}; camera glass_to_wire p50 {server_p50_ms} ms, client capture to arrival {}",
        target["latency"], client["latency"]
    );
}

#[test]
fn webcam_serves_reports_its_mode_and_survives_unplug_and_busy() {
    if !VisionAssets::from_env().is_ready() {
        println!("SKIP: vision models not installed (scripts/setup-vision.sh)");
        return;
    }
    let Some(video) = v4l2_emu::footage().into_iter().next() else {
        return;
    };
    let modes = [
        mode("YUYV", 640, 480, 30),
        mode("MJPG", 640, 480, 60),
        mode("MJPG", 1280, 720, 30),
    ];
    let Some(cam) = v4l2_emu::camera(0, "Emulated Cam", &modes, &video, 60) else {
        return;
    };
    let home = cam.state.join("home");
    std::fs::create_dir_all(&home).unwrap();

    // `rigcast devices` lists the camera, its modes, and the VMC ports in use.
    let out = rigcast(&cam, &home).arg("devices").output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("0: Emulated Cam"), "{text}");
    assert!(text.contains("MJPG 1280x720 @ 30 fps"), "{text}");
    assert!(text.contains("YUYV 640x480 @ 30 fps"), "{text}");
    assert!(text.contains("VMC ports in use"), "{text}");

    let server = serve(
        &cam,
        &home,
        "webcam:0?width=1280&height=720&fps=30&model=full",
    );
    let h = wait_for(server.port, "webcam:0", 120, "live with stage times", |h| {
        h["state"] == "live"
            && h["camera"]["stages"]
                .as_array()
                .is_some_and(|s| !s.is_empty())
    });
    let c = &h["camera"];
    assert_eq!(
        (&c["width"], &c["height"], &c["fps"], &c["format"]),
        (
            &Value::from(1280),
            &Value::from(720),
            &Value::from(30),
            &Value::from("MJPG")
        ),
        "{h}"
    );
    assert_eq!(c["model"], "full", "{h}");
    let stages: Vec<&str> = c["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        stages,
        [
            "capture",
            "decode",
            "detect",
            "landmarks",
            "solve",
            "glass_to_pose"
        ]
    );
    println!("live: {h}");
    wire_latency_matches_a_client(&cam, &home, server.port);

    // A second server on the same camera is told it is busy.
    let out = rigcast(&cam, &home)
        .args(["serve", "--no-mapping-cache", "--listen", "127.0.0.1:0"])
        .args(["--source", "webcam:0?width=640&height=480&fps=30"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "a second server streamed a busy camera"
    );
    assert!(
        err.contains("busy") && err.contains("Emulated Cam"),
        "{err}"
    );

    // Unplugged mid-stream: lost, with the camera named as the reason (a source already lost
    // because the tracker sees nobody in the footage's frame at that moment says "no person
    // in view": not this loss); then back when the camera returns: its frames flow again and
    // the camera is no longer the reason.
    cam.unplug();
    let names_camera =
        |h: &serde_json::Value| h["detail"].as_str().is_some_and(|d| d.contains("camera 0"));
    let h = wait_for(
        server.port,
        "webcam:0",
        10,
        "lost, naming the camera",
        |h| h["state"] == "lost" && names_camera(h),
    );
    let frames_lost = h["frames"].as_u64().unwrap();
    std::thread::sleep(Duration::from_secs(1));
    cam.replug();
    let h = wait_for(server.port, "webcam:0", 30, "back", |h| {
        h["frames"].as_u64().unwrap() > frames_lost && !names_camera(h)
    });
    println!("back: {h}");
}
