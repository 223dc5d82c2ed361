//! Bounded resources of the real `rigcast` binary: memory under clients that announce huge
//! frames, the connection cap at a 1,024 open-file limit, the control token's file, and the
//! warning on a listener beyond loopback. Figures are printed for BENCHMARKS.md.
//!
//! All sockets are loopback; every loop is bounded in count and time.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::os::unix::fs::PermissionsExt;
use std::time::{Duration, Instant};

use rigcast_tests::*;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const MIB: u64 = 1024;

fn fresh_config_home(name: &str) -> std::path::PathBuf {
    let dir = temp_path(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Opens a WebSocket by hand and returns the socket after the 101 head.
async fn raw_upgrade(addr: SocketAddr) -> Option<TcpStream> {
    let mut s = TcpStream::connect(addr).await.ok()?;
    s.write_all(
        b"GET /v1/stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
          Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n",
    )
    .await
    .ok()?;
    let mut head = Vec::new();
    while !head.ends_with(b"\r\n\r\n") {
        head.push(s.read_u8().await.ok()?);
    }
    head.starts_with(b"HTTP/1.1 101").then_some(s)
}

/// One attacker: a masked frame header announcing 16 MB, then up to 15 MiB of its payload in
/// 64 KiB writes, as fast as the server takes them. Returns the bytes the server accepted and
/// the socket (`None`: the upgrade itself failed, which would make the measurement void).
async fn half_sent_frame(addr: SocketAddr) -> (u64, Option<TcpStream>) {
    let Some(mut s) = raw_upgrade(addr).await else {
        return (0, None);
    };
    let mut header = vec![0x82u8, 0x80 | 127];
    header.extend_from_slice(&(16u64 << 20).to_be_bytes());
    header.extend_from_slice(&[9, 9, 9, 9]);
    if s.write_all(&header).await.is_err() {
        return (0, None);
    }
    let chunk = vec![0x55u8; 64 * 1024];
    let mut sent = 0u64;
    while sent < 15 << 20 {
        match tokio::time::timeout(Duration::from_secs(2), s.write_all(&chunk)).await {
            Ok(Ok(())) => sent += chunk.len() as u64,
            // Closed by the server, or it stopped reading: either way no more is buffered.
            _ => break,
        }
    }
    (sent, Some(s))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn memory_stays_bounded_under_half_sent_huge_frames_and_returns() {
    let server = tokio::task::spawn_blocking(|| {
        ServeProcess::start(
            &["--no-mapping-cache"],
            fresh_config_home("xdg-memory"),
            None,
        )
    })
    .await
    .unwrap();
    let addr = server.addr;
    // Warm up what a normal client costs, then let it settle.
    let mut ws = connect(&format!("ws://{addr}/v1/stream")).await;
    handshake(&mut ws).await;
    assert!(!collect_frames(&mut ws, Duration::from_secs(1))
        .await
        .is_empty());
    drop(ws);
    tokio::time::sleep(Duration::from_secs(1)).await;
    let baseline = server.rss_kib();
    let bound = baseline + 50 * MIB;
    let mut floors = Vec::new();
    let mut peaks = Vec::new();
    // Three rounds: a floor that grows round after round is a leak.
    for round in 0..3 {
        let attackers: Vec<_> = (0..40)
            .map(|_| tokio::spawn(half_sent_frame(addr)))
            .collect();
        let mut peak = 0;
        let t0 = Instant::now();
        while !attackers.iter().all(|a| a.is_finished()) && t0.elapsed() < Duration::from_secs(30) {
            peak = peak.max(server.rss_kib());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let mut held = Vec::new();
        let mut accepted = 0;
        for a in attackers {
            let (sent, socket) = a.await.unwrap();
            accepted += sent;
            held.extend(socket);
        }
        assert_eq!(
            held.len(),
            40,
            "every attacker was upgraded and sent its frame header"
        );
        // Hold the connections open for a moment, still sampling.
        for _ in 0..25 {
            peak = peak.max(server.rss_kib());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        drop(held);
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let after = server.rss_kib();
        eprintln!(
            "round {round}: baseline {baseline} KiB, peak {peak} KiB (+{} KiB), after {after} KiB; \
             the server took {} KiB of payload per attacker on average",
            peak.saturating_sub(baseline),
            accepted / 40 / 1024
        );
        assert!(
            peak < bound,
            "peak RSS {peak} KiB over the bound {bound} KiB"
        );
        peaks.push(peak);
        floors.push(after);
    }
    for after in &floors {
        assert!(
            (*after as f64) <= baseline as f64 * 1.10,
            "RSS after the attackers left: {after} KiB vs baseline {baseline} KiB (floors {floors:?})"
        );
    }
    // The server still serves.
    let mut ws = connect(&format!("ws://{addr}/v1/stream")).await;
    handshake(&mut ws).await;
    println!(
        "half-sent 16 MB frames ×40: baseline {baseline} KiB, peaks {peaks:?}, after {floors:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn at_1024_open_files_2000_idle_sockets_do_not_lock_out_a_viewer() {
    let server = tokio::task::spawn_blocking(|| {
        ServeProcess::start(
            &["--no-mapping-cache"],
            fresh_config_home("xdg-fds"),
            Some(1024),
        )
    })
    .await
    .unwrap();
    let addr = server.addr;
    let report = server.output();
    assert!(
        report
            .iter()
            .any(|l| l.contains("connections: at most 960 (open-file limit 1024)")),
        "{report:?}"
    );
    // This test holds 2,000 sockets itself.
    let own = rigcast_server::limits::raise_fd_limit().unwrap();
    assert!(
        own.soft >= 2_200,
        "the test process needs 2,200 open files: {own:?}"
    );
    let t0 = Instant::now();
    let mut idle = Vec::new();
    for _ in 0..2000 {
        let s = tokio::time::timeout(Duration::from_secs(5), TcpStream::connect(addr))
            .await
            .expect("connect within 5 s")
            .expect("connect");
        idle.push(s);
    }
    eprintln!("2000 idle connections opened in {:?}", t0.elapsed());
    // A viewer still gets in and gets frames.
    let t1 = Instant::now();
    let mut ws = tokio::time::timeout(
        Duration::from_secs(5),
        tokio_tungstenite::connect_async(format!("ws://{addr}/v1/stream")),
    )
    .await
    .expect("viewer connected within 5 s")
    .unwrap()
    .0;
    handshake(&mut ws).await;
    let frames = collect_frames(&mut ws, Duration::from_secs(1)).await;
    assert!(frames.len() >= 20, "only {} frames", frames.len());
    eprintln!("viewer connected and streaming after {:?}", t1.elapsed());
    // The excess was told why: the oldest idle sockets got a 503 and were closed.
    let mut refusal = String::new();
    let _ =
        tokio::time::timeout(Duration::from_secs(2), idle[0].read_to_string(&mut refusal)).await;
    assert!(refusal.starts_with("HTTP/1.1 503"), "{refusal:?}");
    assert!(refusal.contains("server full"), "{refusal:?}");
    let (_, body) = http_get(addr, "/v1/status").await;
    let status: serde_json::Value = serde_json::from_str(&body).unwrap();
    let c = &status["connections"];
    assert_eq!(c["max"], 960, "{c}");
    assert_eq!(c["fd_limit"], 1024, "{c}");
    assert!(c["open"].as_u64().unwrap() <= 960 + 16, "{c}");
    // Every socket beyond the cap was answered 503: evicted while idle, or refused at once
    // while evicted ones were still closing.
    assert!(c["refused_total"].as_u64().unwrap() >= 2000 - 960, "{c}");
    assert!(c["evicted_total"].as_u64().unwrap() >= 1, "{c}");
    drop(idle);
    drop(ws);
    tokio::time::sleep(Duration::from_millis(500)).await;
    let out = server.output();
    assert!(
        !out.iter().any(|l| l.contains("Too many open files")),
        "the server ran out of descriptors: {:?}",
        out.iter()
            .filter(|l| l.contains("accept"))
            .take(3)
            .collect::<Vec<_>>()
    );
    println!("2000 idle sockets at ulimit -n 1024: {c}");
}

#[test]
fn control_token_is_created_private_printed_once_and_rotatable() {
    let home = fresh_config_home("xdg-token");
    let token_file = home.join("rigcast").join("token");
    let first = ServeProcess::start(&["--no-mapping-cache"], home.clone(), None);
    let printed = first.output();
    drop(first);
    let token = std::fs::read_to_string(&token_file)
        .unwrap()
        .trim()
        .to_string();
    assert_eq!(token.len(), 64);
    let mode = std::fs::metadata(&token_file).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    assert!(
        printed
            .iter()
            .any(|l| l.contains("viewer with control: http://")
                && l.contains(&format!("?token={token}"))),
        "{printed:?}"
    );
    // Later starts do not print it again.
    let second = ServeProcess::start(&["--no-mapping-cache"], home.clone(), None);
    let printed = second.output();
    drop(second);
    assert!(!printed.iter().any(|l| l.contains(&token)), "{printed:?}");
    assert!(
        printed.iter().any(|l| l.contains("rigcast token show")),
        "{printed:?}"
    );
    // `rigcast token show` prints it; `rotate` replaces it.
    let run = |args: &[&str]| {
        let out = std::process::Command::new(rigcast_binary())
            .args(args)
            .env("XDG_CONFIG_HOME", &home)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    };
    assert_eq!(run(&["token", "show"]), token);
    let rotated = run(&["token", "rotate"]);
    assert_ne!(rotated, token);
    assert_eq!(
        std::fs::read_to_string(&token_file).unwrap().trim(),
        rotated
    );
    assert_eq!(run(&["token", "show"]), rotated);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn listening_beyond_loopback_warns_and_requires_the_token() {
    let home = fresh_config_home("xdg-network");
    // All interfaces on a port the kernel picks; the test connects through loopback only.
    let server = tokio::task::spawn_blocking(move || {
        ServeProcess::start_on("0.0.0.0:0", &["--no-mapping-cache"], home, None)
    })
    .await
    .unwrap();
    let printed = server.output();
    assert!(
        printed
            .iter()
            .any(|l| l.contains("warning: listening on 0.0.0.0:")
                && l.contains("needs the control token")),
        "{printed:?}"
    );
    let local: SocketAddr = format!("127.0.0.1:{}", server.addr.port()).parse().unwrap();
    let refused = tokio_tungstenite::connect_async(format!("ws://{local}/v1/stream")).await;
    match refused {
        Err(tokio_tungstenite::tungstenite::Error::Http(r)) => assert_eq!(r.status(), 401),
        other => panic!("expected 401, got {other:?}"),
    }
    let token = std::fs::read_to_string(server.config_home.join("rigcast").join("token"))
        .unwrap()
        .trim()
        .to_string();
    let mut ws = connect(&format!("ws://{local}/v1/stream?token={token}")).await;
    handshake(&mut ws).await;
    assert!(!collect_frames(&mut ws, Duration::from_millis(500))
        .await
        .is_empty());
}
