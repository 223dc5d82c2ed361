//! Per-client bounds through the real server: a full server refuses with 503; a client that
//! never reads is dropped after the stall timeout while a slow reader stays; a client whose
//! control queue overflowed still ends up with the current skeletons and mapping.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use futures_util::StreamExt;
use rigcast_protocol::ServerMessage;
use rigcast_retarget::Clip;
use rigcast_server::{LimitsConfig, PerformerSpec, ServerConfig, TargetSpec};
use rigcast_tests::*;
use tokio::io::AsyncReadExt;
use tokio_tungstenite::tungstenite::protocol::Role;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::WebSocketStream;

const WAIT: Duration = Duration::from_secs(5);

/// A chain of `n` bones with a little motion: frames of 60 + 16n bytes.
fn chain_clip(n: usize) -> Clip {
    rigcast_tests::chain_clip(n, 30, 0.05, 0.002, 30.0)
}

async fn status(addr: std::net::SocketAddr) -> serde_json::Value {
    let (_, body) = http_get(addr, "/v1/status").await;
    serde_json::from_str(&body).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_server_refuses_with_503_and_admits_again_when_a_client_leaves() {
    let server = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![clip_source(fixture_clip())],
        limits: LimitsConfig {
            max_connections: Some(3),
            ..LimitsConfig::default()
        },
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let mut clients = Vec::new();
    for _ in 0..3 {
        let mut ws = connect(&server.stream_url()).await;
        handshake(&mut ws).await;
        clients.push(ws);
    }
    match tokio_tungstenite::connect_async(server.stream_url()).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(r)) => {
            assert_eq!(r.status(), 503);
            let body =
                String::from_utf8_lossy(r.body().as_deref().unwrap_or_default()).into_owned();
            assert!(body.contains("server full: 3 connections"), "{body}");
        }
        other => panic!("expected 503, got {other:?}"),
    }
    drop(clients.pop());
    // The slot comes back once the server has noticed the close.
    let deadline = Instant::now() + WAIT;
    loop {
        match tokio_tungstenite::connect_async(server.stream_url()).await {
            Ok((mut ws, _)) => {
                handshake(&mut ws).await;
                clients.push(ws);
                break;
            }
            Err(_) if Instant::now() < deadline => {
                tokio::time::sleep(Duration::from_millis(50)).await
            }
            Err(e) => panic!("no slot after a client left: {e}"),
        }
    }
    // The status request needs a slot of its own.
    drop(clients);
    let deadline = Instant::now() + WAIT;
    let s = loop {
        let (head, body) = http_get(server.local_addr(), "/v1/status").await;
        if head.starts_with("HTTP/1.1 200") {
            break serde_json::from_str::<serde_json::Value>(&body).unwrap();
        }
        assert!(Instant::now() < deadline, "status still refused: {head}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!(s["connections"]["max"], 3);
    assert!(s["connections"]["refused_total"].as_u64() >= Some(1));
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_never_reads_is_dropped_while_a_slow_reader_stays() {
    let server = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz: 120.0,
        // 200 bones: ~3.3 kB frames at 120 Hz fill a stalled socket within a second.
        sources: vec![clip_source(chain_clip(200))],
        limits: LimitsConfig {
            stalled_client_timeout_secs: 1.5,
            ..LimitsConfig::default()
        },
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let addr = server.local_addr();
    let _never_reads = stalled_client(addr).await;
    let mut slow = stalled_client(addr).await;
    // The slow reader takes 4 KiB every 100 ms (~40 kB/s of a ~400 kB/s stream): far behind,
    // but never stuck for long.
    let t0 = Instant::now();
    let mut buf = vec![0u8; 4096];
    let mut dropped_at = None;
    while t0.elapsed() < Duration::from_secs(5) {
        let n = tokio::time::timeout(Duration::from_secs(2), slow.read(&mut buf))
            .await
            .expect("the slow reader keeps receiving")
            .unwrap();
        assert!(n > 0, "the slow reader was disconnected");
        tokio::time::sleep(Duration::from_millis(100)).await;
        if dropped_at.is_none() {
            let s = status(addr).await;
            if s["stalled_disconnects_total"] == 1 {
                dropped_at = Some(t0.elapsed());
            }
        }
    }
    let dropped_at = dropped_at.expect("the client that never reads was dropped within 5 s");
    assert!(
        dropped_at >= Duration::from_millis(1500),
        "dropped after {dropped_at:?}, before the 1.5 s timeout"
    );
    let s = status(addr).await;
    assert_eq!(
        s["stalled_disconnects_total"], 1,
        "only the one that never reads"
    );
    assert_eq!(
        s["clients"]["count"], 1,
        "the slow reader is still connected"
    );
    eprintln!("never-reading client dropped after {dropped_at:?}; slow reader kept for 5 s");
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_whose_control_queue_overflowed_ends_with_the_current_state() {
    let clip = chain_clip(40);
    let skeleton = clip.skeleton.clone();
    let server = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz: 240.0,
        sources: vec![clip_source(clip)],
        performers: vec![PerformerSpec {
            target: TargetSpec::Skeleton {
                skeleton,
                name: "copy".into(),
            },
            ..PerformerSpec::target_file("unused")
        }],
        // Long enough that the stalled client is kept for the whole flood.
        limits: LimitsConfig {
            stalled_client_timeout_secs: 120.0,
            ..LimitsConfig::default()
        },
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let addr = server.local_addr();
    let stalled = stalled_client(addr).await;
    let mut control = connect(&server.control_stream_url()).await;
    handshake(&mut control).await;
    // Far more mapping changes than the 256-message control queue holds, while the stalled
    // client reads nothing. The last one drives b7 from b3 (no earlier state had that).
    let mut accepted = 0;
    let t0 = Instant::now();
    while accepted < 400 && t0.elapsed() < Duration::from_secs(60) {
        let overrides = if accepted == 399 {
            r#"{"b7":"b3"}"#.to_string()
        } else if accepted % 2 == 0 {
            r#"{"b5":null}"#.to_string()
        } else {
            r#"{"b5":"b5"}"#.to_string()
        };
        send_text(
            &mut control,
            &format!(r#"{{"type":"set_mapping","subject":1,"overrides":{overrides}}}"#),
        )
        .await;
        loop {
            match next_json(&mut control, WAIT).await.expect("an answer") {
                ServerMessage::Ack { .. } => {
                    accepted += 1;
                    break;
                }
                // The mapper's queue is full: let it catch up.
                ServerMessage::Error { message, .. } if message.contains("busy") => {
                    tokio::time::sleep(Duration::from_millis(5)).await;
                    break;
                }
                ServerMessage::Error { code, message, .. } => panic!("{code:?}: {message}"),
                _ => {}
            }
        }
    }
    assert_eq!(accepted, 400);
    // Wait until the mapper has applied the last change.
    loop {
        if let ServerMessage::Mapping { entries, .. } =
            next_json(&mut control, WAIT).await.expect("mappings")
        {
            if entries
                .iter()
                .any(|e| e.target == "b7" && e.source.as_deref() == Some("b3"))
            {
                break;
            }
        }
    }
    // What a fresh client is told now is the current state.
    let mut fresh = connect(&server.stream_url()).await;
    let (_, fresh_skeletons) = handshake(&mut fresh).await;
    let fresh_mapping = loop {
        if let m @ ServerMessage::Mapping { .. } = next_json(&mut fresh, WAIT).await.unwrap() {
            break m;
        }
    };
    // The stalled client reads again: it must catch up to exactly that.
    let mut late = WebSocketStream::from_raw_socket(stalled, Role::Client, None).await;
    let mut last_mapping = None;
    let mut last_skeletons = std::collections::BTreeMap::new();
    let mut resynced = false;
    let deadline = Instant::now() + Duration::from_secs(3);
    while let Ok(Some(msg)) = tokio::time::timeout_at(deadline.into(), late.next()).await {
        let Message::Text(t) = msg.unwrap() else {
            continue;
        };
        match serde_json::from_str(t.as_str()).unwrap() {
            ServerMessage::SubjectsChanged { .. } => resynced = true,
            m @ ServerMessage::Mapping { .. } => last_mapping = Some(m),
            ServerMessage::Skeleton {
                subject,
                fingerprint,
                ..
            } => {
                last_skeletons.insert(subject, fingerprint);
            }
            _ => {}
        }
    }
    assert!(resynced, "the overflowed client got a snapshot");
    assert_eq!(
        last_mapping.as_ref(),
        Some(&fresh_mapping),
        "ends with the current mapping"
    );
    for s in &fresh_skeletons {
        let ServerMessage::Skeleton {
            subject,
            fingerprint,
            ..
        } = s
        else {
            unreachable!()
        };
        assert_eq!(
            last_skeletons.get(subject),
            Some(fingerprint),
            "subject {subject}"
        );
    }
    let s = status(addr).await;
    assert!(
        s["control_resyncs_total"].as_u64() >= Some(1),
        "{}",
        s["control_resyncs_total"]
    );
    server.shutdown().await;
}
