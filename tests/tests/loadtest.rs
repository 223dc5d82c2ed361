//! `rigcast loadtest` against a real `rigcast serve` on loopback: every client connects, gets
//! every subject at the tick rate with nothing lagged, and the latencies it reports are
//! plausible; a server that is not there is a short, clear error.
#![allow(clippy::unwrap_used)]

use std::process::Command;

use rigcast_tests::{free_port, rate_plausible, rigcast_binary, temp_path, ServeProcess};
use serde_json::Value;

/// The demo server streams two subjects (the performer and its character) at 60 Hz.
const DEMO_SUBJECTS: usize = 2;
const DEMO_RATE_HZ: f64 = 60.0;

fn fresh_config_home(name: &str) -> std::path::PathBuf {
    let dir = temp_path(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn loadtest(url: &str, clients: usize, secs: f64) -> std::process::Output {
    Command::new(rigcast_binary())
        .args(["loadtest", "--url", url, "--json"])
        .args([
            "--clients",
            &clients.to_string(),
            "--secs",
            &secs.to_string(),
        ])
        .output()
        .expect("rigcast loadtest runs")
}

#[test]
fn fifty_clients_get_every_subject_at_the_tick_rate() {
    let server = ServeProcess::start(&[], fresh_config_home("xdg-loadtest"), None);
    let url = format!("ws://{}/v1/stream", server.addr);
    let out = loadtest(&url, 50, 2.0);
    assert!(
        out.status.success(),
        "loadtest failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).expect("a JSON report");
    println!("{report:#}");
    assert_eq!(report["clients"], 50);
    assert_eq!(report["connected"], 50, "{report}");
    assert_eq!(
        report["subjects"].as_array().map(Vec::len),
        Some(DEMO_SUBJECTS),
        "{report}"
    );
    let per_subject = report["subject_rate_hz"].as_f64().unwrap();
    assert!(rate_plausible(per_subject, DEMO_RATE_HZ), "{report}");
    let slowest = report["client_rate_hz"]["min"].as_f64().unwrap();
    assert!(
        rate_plausible(slowest / DEMO_SUBJECTS as f64, DEMO_RATE_HZ),
        "a client fell behind: {report}"
    );
    assert_eq!(report["lagged"], 0, "{report}");
    assert_eq!(report["missed_frames"], 0, "{report}");
    let p50 = report["latency_us"]["p50"].as_u64().unwrap();
    let max = report["latency_us"]["max"].as_u64().unwrap();
    // Loopback: well under a second, and stamped before arrival (not zero for every frame).
    assert!(max > 0 && p50 <= max && max < 1_000_000, "{report}");
}

#[test]
fn no_server_is_a_short_clear_error() {
    let url = format!("ws://127.0.0.1:{}/v1/stream", free_port());
    let out = loadtest(&url, 3, 0.5);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no client could connect"), "{err}");
    assert!(err.len() < 600, "error too long: {err}");
}

#[test]
fn zero_clients_is_refused() {
    let out = loadtest("ws://127.0.0.1:1/v1/stream", 0, 1.0);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--clients must be at least 1"));
}

#[test]
fn a_warm_up_out_of_range_is_refused() {
    for bad in ["-1", "NaN", "inf", "3601"] {
        let out = Command::new(rigcast_binary())
            .args(["loadtest", "--url", "ws://127.0.0.1:1/v1/stream"])
            .arg(format!("--warm-up={bad}"))
            .output()
            .expect("rigcast loadtest runs");
        assert!(!out.status.success(), "--warm-up {bad} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--warm-up must be 0 to 3600 seconds"),
            "{bad}: {err}"
        );
    }
}
