//! Hostile VMC input to the real `rigcast serve` binary: datagrams whose values are each finite
//! but overflow once combined (the root's and the hips' positions at 3e38 m sum to infinity),
//! and OSC messages nesting arrays thousands deep. The server must keep streaming every other
//! subject at the full rate, report the bad one, and take it back once its input is sane.
#![allow(clippy::unwrap_used)]

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_protocol::vmc::VmcEncoder;
use rigcast_protocol::ServerMessage;
use rigcast_tests::*;
use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};

const RATE: f64 = 60.0;

/// What a sender thread sends: sane frames, the hostile datagram, or nothing.
const SANE: u8 = 0;
const HOSTILE: u8 = 1;
const STOP: u8 = 2;

/// The datagram of the report: root position and hips position each 3e38 (finite), plus the
/// time message; 184 bytes.
fn overflowing_datagram(t: f32) -> Vec<u8> {
    let big = OscType::Float(3e38);
    let rot = [0.0, 0.0, 0.0, 1.0].map(OscType::Float);
    let pos = |addr: &str, name: &str| {
        let mut args = vec![
            OscType::String(name.into()),
            big.clone(),
            big.clone(),
            big.clone(),
        ];
        args.extend(rot.iter().cloned());
        OscPacket::Message(OscMessage {
            addr: addr.into(),
            args,
        })
    };
    let packet = OscPacket::Bundle(OscBundle {
        timetag: OscTime::from((0, 1)),
        content: vec![
            pos("/VMC/Ext/Root/Pos", "root"),
            pos("/VMC/Ext/Bone/Pos", "Hips"),
            OscPacket::Message(OscMessage {
                addr: "/VMC/Ext/T".into(),
                args: vec![OscType::Float(t)],
            }),
        ],
    });
    rosc::encoder::encode(&packet).unwrap()
}

/// An OSC message whose type tags open `depth` arrays (`,[[[…]]]`): one datagram, which a
/// recursive decoder (or the recursive drop of what it decoded) overflows the stack on.
fn nested_array_datagram(depth: usize) -> Vec<u8> {
    let mut out = Vec::new();
    let pad = |out: &mut Vec<u8>| {
        out.push(0);
        while out.len() % 4 != 0 {
            out.push(0);
        }
    };
    out.extend_from_slice(b"/VMC/Ext/Bone/Pos");
    pad(&mut out);
    out.push(b',');
    out.extend(std::iter::repeat_n(b'[', depth));
    out.extend(std::iter::repeat_n(b']', depth));
    pad(&mut out);
    out
}

/// Streams the procedural humanoid to `to` at [`RATE`] while `mode` is [`SANE`], the overflowing
/// datagram while it is [`HOSTILE`]; stops at [`STOP`].
fn sender(to: SocketAddr, mode: Arc<AtomicU8>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let clip = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
        let names = clip.skeleton.names().to_vec();
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut enc = VmcEncoder::new();
        let t0 = Instant::now();
        let mut k = 0usize;
        loop {
            let t = t0.elapsed().as_secs_f32();
            match mode.load(Ordering::Relaxed) {
                SANE => {
                    let pose = &clip.poses[k % clip.poses.len()];
                    send_vmc_pose(&socket, to, &mut enc, &names, pose, t);
                }
                HOSTILE => {
                    let d = overflowing_datagram(t);
                    assert_eq!(d.len(), 184);
                    socket.send_to(&d, to).unwrap();
                }
                _ => return,
            }
            k += 1;
            std::thread::sleep(Duration::from_secs_f64(1.0 / RATE));
        }
    })
}

fn config_file(port_a: u16, port_b: u16) -> std::path::PathBuf {
    let path = temp_path("hostile_vmc.toml");
    let text = format!(
        "rate_hz = {RATE}\nmapping_cache = false\n\
         [[sources]]\nkind = \"vmc\"\nport = {port_a}\nname = \"bad\"\nlost_after_secs = 5.0\n\
         [[sources]]\nkind = \"vmc\"\nport = {port_b}\nname = \"good\"\nlost_after_secs = 5.0\n\
         [[performers]]\nsource = \"bad\"\ntarget = \"builtin:mannequin\"\nname = \"bad_target\"\n\
         [[performers]]\nsource = \"good\"\ntarget = \"builtin:mannequin\"\nname = \"good_target\"\n"
    );
    std::fs::write(&path, text).unwrap();
    path
}

async fn status(addr: SocketAddr) -> serde_json::Value {
    let (_, body) = http_get(addr, "/v1/status").await;
    serde_json::from_str(&body).unwrap()
}

fn subject<'a>(status: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    status["subjects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .unwrap_or_else(|| panic!("no subject {name} in {status}"))
}

/// Per subject id over `span`: frames received, highest seq, and whether every value was
/// finite.
async fn watch_subjects(
    ws: &mut Ws,
    span: Duration,
) -> std::collections::BTreeMap<u32, (usize, u64, bool)> {
    let mut seen = std::collections::BTreeMap::new();
    for (f, _) in collect_frames(ws, span).await {
        let finite = f.rotations.iter().all(|q| q.is_finite()) && f.root.is_finite();
        let e = seen.entry(f.header.subject).or_insert((0, 0, true));
        e.0 += 1;
        e.1 = e.1.max(f.header.seq);
        e.2 &= finite;
    }
    seen
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_overflowing_vmc_datagram_is_refused_and_the_other_subjects_stream_on() {
    let (port_a, port_b) = (free_udp_port(), free_udp_port());
    let config = config_file(port_a, port_b);
    let server = ServeProcess::start(
        &["--config", config.to_str().unwrap()],
        temp_path("hostile_vmc_home"),
        None,
    );
    let to = |port| SocketAddr::from(([127, 0, 0, 1], port));
    let (mode_a, mode_b) = (Arc::new(AtomicU8::new(SANE)), Arc::new(AtomicU8::new(SANE)));
    let threads = [
        sender(to(port_a), mode_a.clone()),
        sender(to(port_b), mode_b.clone()),
    ];
    let mut ws = connect(&format!("ws://{}/v1/stream", server.addr)).await;
    let (hello, _) = handshake(&mut ws).await;
    let ServerMessage::Hello { subjects, .. } = hello else {
        unreachable!()
    };
    let id = |name: &str| subjects.iter().find(|s| s.name == name).unwrap().id;
    let (bad, good_target, bad_target) = (id("bad"), id("good_target"), id("bad_target"));
    // Both targets move before anything hostile arrives (mapping built, frames flowing).
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let seen = watch_subjects(&mut ws, Duration::from_millis(500)).await;
        let moving = |s| seen.get(&s).is_some_and(|e| e.1 > 5);
        if moving(good_target) && moving(bad_target) {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "targets never streamed: {seen:?}"
        );
    }
    let before = status(server.addr).await;
    let pre = watch_subjects(&mut ws, Duration::from_millis(300)).await;

    mode_a.store(HOSTILE, Ordering::Relaxed);
    // The hostile input's first datagrams arrive meanwhile. Frames are read (and dropped)
    // rather than left to queue: a queue's backlog, read at the start of the measured span,
    // would count as frames of that span (0.2 s of them: 66 Hz measured at 60).
    watch_subjects(&mut ws, Duration::from_millis(200)).await;
    let span = Duration::from_secs(2);
    let during = watch_subjects(&mut ws, span).await;
    let after = status(server.addr).await;
    for (subject, (frames, _, finite)) in &during {
        assert!(
            finite,
            "subject {subject} streamed a non-finite value: {during:?}"
        );
        let hz = *frames as f64 / span.as_secs_f64();
        assert!(
            rate_plausible(hz, RATE),
            "subject {subject} at {hz:.1} Hz while another subject's input was hostile"
        );
    }
    assert!(
        during[&good_target].1 > pre[&good_target].1 + 60,
        "the good target kept its motion: {during:?}"
    );
    let refused = subject(&after, "bad")["rejected_poses"].as_u64().unwrap();
    let refused_before = subject(&before, "bad")["rejected_poses"].as_u64().unwrap();
    assert!(refused > refused_before + 30, "bad poses counted: {after}");
    let why = subject(&after, "bad")["last_rejection"].as_str().unwrap();
    // Root + hips: each finite, their sum not.
    assert!(why.contains("Hips") && why.contains("not finite"), "{why}");
    assert_eq!(subject(&after, "good")["rejected_poses"], 0);
    let source = &after["subjects"][bad as usize]["source"];
    assert!(
        source["detail"]
            .as_str()
            .unwrap()
            .starts_with("poses refused"),
        "{source}"
    );
    // The bad target holds its last good pose: it publishes nothing new meanwhile.
    assert!(
        during[&bad_target].1 <= pre[&bad_target].1 + 15,
        "{during:?}"
    );

    // Sane input again: the bad source's target moves again.
    mode_a.store(SANE, Ordering::Relaxed);
    tokio::time::sleep(Duration::from_millis(300)).await;
    let back = watch_subjects(&mut ws, Duration::from_secs(1)).await;
    assert!(
        back[&bad_target].1 > during[&bad_target].1 + 20,
        "the target of the once-bad source moves again: {back:?}"
    );
    assert!(back.values().all(|e| e.2));
    mode_a.store(STOP, Ordering::Relaxed);
    mode_b.store(STOP, Ordering::Relaxed);
    for t in threads {
        t.join().unwrap();
    }
    let out = server.output().join("\n");
    assert!(!out.contains("panicked"), "{out}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn osc_arrays_nested_thousands_deep_are_dropped_without_harm() {
    let (port_a, port_b) = (free_udp_port(), free_udp_port());
    let config = config_file(port_a, port_b);
    let server = ServeProcess::start(
        &["--config", config.to_str().unwrap()],
        temp_path("hostile_osc_home"),
        None,
    );
    let to = SocketAddr::from(([127, 0, 0, 1], port_a));
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    for depth in [9, 100, 32_700] {
        let d = nested_array_datagram(depth);
        assert!(d.len() < 65_507);
        for _ in 0..5 {
            socket.send_to(&d, to).unwrap();
        }
    }
    // Then sane input to the same source is decoded as usual.
    let mode = Arc::new(AtomicU8::new(SANE));
    let thread = sender(to, mode.clone());
    let deadline = Instant::now() + Duration::from_secs(15);
    let live = loop {
        let s = status(server.addr).await;
        let bad = subject(&s, "bad");
        if bad["source"]["state"] == "live" && bad["input_frames"].as_u64().unwrap() > 10 {
            break s;
        }
        assert!(
            Instant::now() < deadline,
            "the source never turned live: {s}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    let dropped = subject(&live, "bad")["source"]["dropped"].as_u64().unwrap();
    assert!(
        dropped >= 10,
        "the nested datagrams are counted as dropped: {live}"
    );
    mode.store(STOP, Ordering::Relaxed);
    thread.join().unwrap();
    let out = server.output().join("\n");
    assert!(
        !out.contains("overflow") && !out.contains("panicked"),
        "{out}"
    );
}

fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}
