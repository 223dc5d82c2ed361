//! `GET /v1/status` returns the documented fields with live values.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use rigcast_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn status_reports_documented_fields() {
    let server = start_server(vec![clip_source(fixture_clip())], 50.0, vec![]).await;
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    collect_frames(&mut ws, Duration::from_millis(1200)).await;

    let (head, body) = http_get(server.local_addr(), "/v1/status").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(head.contains("application/json"));
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(v["tick_hz"], 50.0);
    let out = v["output_rate_hz"].as_f64().unwrap();
    assert!(rate_plausible(out, 50.0), "output rate {out}");
    let s = &v["subjects"][0];
    assert_eq!(s["id"], 0);
    assert_eq!(s["name"], "fixture");
    assert_eq!(s["num_bones"], 6);
    let fps = s["input_fps"].as_f64().unwrap();
    assert!(rate_plausible(fps, 30.0), "input fps {fps}");
    let last = s["last_capture_nanos"].as_u64().unwrap();
    assert!(unix_nanos() - last < 2_000_000_000);
    assert!(s["input_frames"].as_u64().unwrap() > 10);
    assert_eq!(v["clients"]["count"], 1);
    let c = &v["clients"]["list"][0];
    assert!(c["frames_sent"].as_u64().unwrap() > 10);
    assert_eq!(c["missed_frames"], 0);
    assert_eq!(v["dropped_frames_total"], 0);
    let t = &v["tick_micros"];
    for k in ["p50", "p90", "p99", "max"] {
        assert!(t[k].is_u64(), "{k}");
    }
    assert!(t["p50"].as_u64() <= t["p99"].as_u64());
    assert!(t["p99"].as_u64() <= t["max"].as_u64());
    assert!(t["samples"].as_u64().unwrap() > 10);

    // The viewer page and a 404.
    let (head, body) = http_get(server.local_addr(), "/").await;
    assert!(head.starts_with("HTTP/1.1 200") && body.contains("rigcast"));
    let (head, _) = http_get(server.local_addr(), "/no/such/file").await;
    assert!(head.starts_with("HTTP/1.1 404"), "{head}");
    // The stream endpoint without an upgrade.
    let (head, _) = http_get(server.local_addr(), "/v1/stream").await;
    assert!(head.starts_with("HTTP/1.1 426"), "{head}");
    server.shutdown().await;
}

/// A recording whose writes fail (the disk is full) keeps the server running and says so in
/// the status, instead of counting failures nobody reads.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn recording_errors_show_in_the_status() {
    let full = std::path::Path::new("/dev/full");
    if !full.exists() {
        eprintln!("SKIP: no /dev/full on this system");
        return;
    }
    let server = rigcast_server::start(rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![clip_source(fixture_clip())],
        record: Some(full.to_path_buf()),
        ..rigcast_server::ServerConfig::default()
    })
    .await
    .unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    let recording = loop {
        let (_, body) = http_get(server.local_addr(), "/v1/status").await;
        let status: serde_json::Value = serde_json::from_str(&body).unwrap();
        let recording = status["recording"].clone();
        if recording["errors"].as_u64() > Some(0) || std::time::Instant::now() > deadline {
            break recording;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    assert_eq!(recording["path"], "/dev/full", "{recording}");
    assert!(recording["errors"].as_u64() > Some(0), "{recording}");
    let last = recording["last_error"].as_str().unwrap_or_default();
    assert!(last.contains("space"), "{recording}");
    // Frames still flow.
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    assert!(!collect_frames(&mut ws, Duration::from_millis(300))
        .await
        .is_empty());
    server.shutdown().await;
}
