//! `rigcast loadtest --url ws://… --clients N --secs S [--json]`: opens N ordinary WebSocket
//! clients against a running server, reads every frame for S seconds and reports what each
//! client got: frames per second (per client, and per subject), latency from the frame's
//! `send_nanos` (stamped when the server encoded it) to its arrival here, `lagged` notices and
//! the frames the server reports a client missed; and per subject, from each new frame's
//! `capture_nanos` (a camera frame's driver timestamp: glass) to its arrival here.
//!
//! Latency is measured against this machine's clock, so it is meaningful on loopback or
//! between clock-synchronised machines. Frames that arrive before every client is connected
//! (plus a short warm-up, `--warm-up`) are not counted, so slow connects do not skew the rates.
//! With `--warm-up 0` a single client counts every frame the server writes to it, so its
//! figures can be set against the server's own `/v1/status` latencies frame for frame.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context};
use clap::Args;
use futures_util::StreamExt;
use rigcast_protocol::frame::decode_header_any;
use serde::Serialize;
use tokio::sync::{Barrier, Semaphore};
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::Message;

/// Connections opened at once (a burst of thousands overflows the listen backlog).
const CONNECTS_IN_FLIGHT: usize = 64;
/// How long a client may take to connect before it counts as failed.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);
/// Read buffer per client. tungstenite zero-fills the free part of its read buffer before
/// every read; at its 128 KiB default that memset was most of this tool's own time, and the
/// tool shares the cores with the server it measures. A tick's frames are a few KiB.
const READ_BUFFER_BYTES: usize = 4 * 1024;

/// Options of `rigcast loadtest`.
#[derive(Debug, Args)]
pub struct LoadtestArgs {
    /// Server stream URL.
    #[arg(long, default_value = "ws://127.0.0.1:8717/v1/stream")]
    pub url: String,
    /// Number of clients to open.
    #[arg(long, default_value_t = 10)]
    pub clients: usize,
    /// Seconds to measure (after every client is connected).
    #[arg(long, default_value_t = 5.0)]
    pub secs: f64,
    /// Seconds after every client is connected whose frames are not counted (0: count from
    /// the first frame, as the server's own status does).
    #[arg(long, default_value_t = 0.5)]
    pub warm_up: f64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// What one client saw in the measured window.
#[derive(Debug, Default)]
struct ClientLog {
    frames: u64,
    lagged: u64,
    missed: u64,
    /// Arrival minus `send_nanos`, microseconds, one per frame.
    latencies_us: Vec<u32>,
    subjects: BTreeSet<u32>,
    /// Per subject: the last capture time seen and arrival minus capture of every frame with
    /// a new one (ticks repeat a frame until its source produces the next), microseconds.
    glass: BTreeMap<u32, (u64, Vec<u32>)>,
    error: Option<String>,
}

/// The report, as printed with `--json`.
#[derive(Debug, Serialize, PartialEq)]
pub struct LoadReport {
    /// The stream URL measured.
    pub url: String,
    /// Clients opened.
    pub clients: usize,
    /// Clients that connected and received frames or closed cleanly.
    pub connected: usize,
    /// Length of the measured window, seconds.
    pub secs: f64,
    /// Subject ids seen by any client.
    pub subjects: Vec<u32>,
    /// Frames per second received by each client (all subjects together).
    pub client_rate_hz: Spread,
    /// Frames per second per subject, mean over clients.
    pub subject_rate_hz: f64,
    /// Arrival minus `send_nanos` over every frame of every client, microseconds.
    pub latency_us: Percentiles,
    /// Per subject, arrival minus `capture_nanos` of every frame with a new capture time
    /// (glass to arrival for a camera), over every client, microseconds.
    pub glass_us: Vec<SubjectGlass>,
    /// `lagged` notices received (the server dropped frames for a slow client).
    pub lagged: u64,
    /// Frames the server reported missed in frame headers.
    pub missed_frames: u64,
    /// The first few connection or transport errors.
    pub errors: Vec<String>,
}

/// Minimum, mean and maximum of a per-client figure.
#[derive(Debug, Serialize, PartialEq, Default)]
pub struct Spread {
    /// Lowest.
    pub min: f64,
    /// Mean.
    pub mean: f64,
    /// Highest.
    pub max: f64,
}

/// One subject's capture-to-arrival latency.
#[derive(Debug, Serialize, PartialEq, Default)]
pub struct SubjectGlass {
    /// Subject id.
    pub subject: u32,
    /// Frames with a new capture time, over every client.
    pub frames: usize,
    /// Arrival minus capture time, microseconds.
    pub latency: Percentiles,
}

/// Latency percentiles.
#[derive(Debug, Serialize, PartialEq, Default)]
pub struct Percentiles {
    /// Median.
    pub p50: u32,
    /// 90th percentile.
    pub p90: u32,
    /// 99th percentile.
    pub p99: u32,
    /// 99.9th percentile.
    pub p999: u32,
    /// Largest.
    pub max: u32,
}

/// Runs `rigcast loadtest`.
pub async fn run(args: LoadtestArgs) -> anyhow::Result<()> {
    if args.clients == 0 {
        bail!("--clients must be at least 1");
    }
    if !(args.secs.is_finite() && args.secs > 0.0) {
        bail!("--secs must be a positive number of seconds");
    }
    if !(args.warm_up.is_finite() && (0.0..=3600.0).contains(&args.warm_up)) {
        bail!("--warm-up must be 0 to 3600 seconds");
    }
    if !args.json {
        eprintln!(
            "loadtest: {} clients on {} for {:.1} s",
            args.clients, args.url, args.secs
        );
    }
    let window = Window {
        warm_up: Duration::from_secs_f64(args.warm_up),
        secs: Duration::from_secs_f64(args.secs),
    };
    let report = measure(&args.url, args.clients, window).await?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report);
    }
    if report.connected == 0 {
        bail!(
            "no client could connect to {}: {}",
            report.url,
            report
                .errors
                .first()
                .map(String::as_str)
                .unwrap_or("unknown error")
        );
    }
    Ok(())
}

/// What each client counts, from the moment every client is connected.
#[derive(Debug, Clone, Copy)]
pub struct Window {
    /// Not counted first.
    pub warm_up: Duration,
    /// Then counted.
    pub secs: Duration,
}

/// Opens `clients` clients on `url`, measures over `window` once all are connected, and
/// reports.
pub async fn measure(url: &str, clients: usize, window: Window) -> anyhow::Result<LoadReport> {
    url.parse::<tokio_tungstenite::tungstenite::http::Uri>()
        .with_context(|| format!("not a WebSocket URL: {url}"))?;
    let connects = Arc::new(Semaphore::new(CONNECTS_IN_FLIGHT));
    // Every client task (connected or not) plus this one meet here before measuring.
    let ready = Arc::new(Barrier::new(clients + 1));
    let mut tasks = Vec::with_capacity(clients);
    for _ in 0..clients {
        let (url, connects, ready) = (url.to_string(), connects.clone(), ready.clone());
        tasks.push(tokio::spawn(async move {
            client(&url, &connects, &ready, window).await
        }));
    }
    ready.wait().await;
    let mut logs = Vec::with_capacity(clients);
    for t in tasks {
        logs.push(t.await.unwrap_or_else(|e| ClientLog {
            error: Some(format!("client task failed: {e}")),
            ..ClientLog::default()
        }));
    }
    Ok(summarise(url, window.secs.as_secs_f64(), &logs))
}

/// One client: connect, wait for the others, then read until the window closes.
async fn client(url: &str, connects: &Semaphore, ready: &Barrier, window: Window) -> ClientLog {
    let mut log = ClientLog::default();
    let ws = {
        let _permit = connects.acquire().await;
        let config = WebSocketConfig::default().read_buffer_size(READ_BUFFER_BYTES);
        let connect = tokio_tungstenite::connect_async_with_config(url, Some(config), true);
        tokio::time::timeout(CONNECT_TIMEOUT, connect).await
    };
    let ws = match ws {
        Ok(Ok((ws, _))) => Some(ws),
        Ok(Err(e)) => {
            log.error = Some(format!("connect: {e}"));
            None
        }
        Err(_) => {
            log.error = Some(format!("connect: no answer in {CONNECT_TIMEOUT:?}"));
            None
        }
    };
    ready.wait().await;
    let Some(mut ws) = ws else {
        return log;
    };
    let start = Instant::now() + window.warm_up;
    let end = start + window.secs;
    log.latencies_us
        .reserve((window.secs.as_secs_f64() * 500.0) as usize);
    // One timer for the whole window: a timeout per read would register a timer for every
    // frame of every client, and the load tool's own overhead is part of what it measures.
    let window = tokio::time::sleep_until(tokio::time::Instant::from_std(end));
    tokio::pin!(window);
    // The clock check too: a socket that always has data would never let the timer win.
    while Instant::now() < end {
        let next = tokio::select! {
            biased;
            next = ws.next() => next,
            () = &mut window => break,
        };
        let msg = match next {
            None => {
                log.error = Some("server closed the connection".into());
                break;
            }
            Some(Err(e)) => {
                log.error = Some(format!("transport: {e}"));
                break;
            }
            Some(Ok(m)) => m,
        };
        if Instant::now() < start {
            continue;
        }
        record(&mut log, &msg);
    }
    log
}

/// Counts one message into `log`.
fn record(log: &mut ClientLog, msg: &Message) {
    match msg {
        Message::Binary(bytes) => {
            let Ok((header, _)) = decode_header_any(bytes) else {
                return;
            };
            let now = unix_nanos();
            let us = now.saturating_sub(header.send_nanos) / 1_000;
            log.latencies_us.push(us.min(u64::from(u32::MAX)) as u32);
            log.frames += 1;
            log.missed += u64::from(header.missed_frames);
            log.subjects.insert(header.subject);
            let (last, glass) = log.glass.entry(header.subject).or_default();
            if header.capture_nanos > *last {
                *last = header.capture_nanos;
                let us = now.saturating_sub(header.capture_nanos) / 1_000;
                glass.push(us.min(u64::from(u32::MAX)) as u32);
            }
        }
        Message::Text(text) if text.contains("\"lagged\"") => log.lagged += 1,
        _ => {}
    }
}

fn unix_nanos() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// The report over every client's log.
fn summarise(url: &str, secs: f64, logs: &[ClientLog]) -> LoadReport {
    let connected: Vec<&ClientLog> = logs
        .iter()
        .filter(|l| l.frames > 0 || l.error.is_none())
        .collect();
    let subjects: BTreeSet<u32> = logs
        .iter()
        .flat_map(|l| l.subjects.iter().copied())
        .collect();
    let rates: Vec<f64> = connected.iter().map(|l| l.frames as f64 / secs).collect();
    let mut latencies: Vec<u32> = logs
        .iter()
        .flat_map(|l| l.latencies_us.iter().copied())
        .collect();
    latencies.sort_unstable();
    let mean = |v: &[f64]| {
        if v.is_empty() {
            0.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let client_rate_hz = Spread {
        min: rates
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .min(f64::MAX),
        mean: mean(&rates),
        max: rates.iter().copied().fold(0.0, f64::max),
    };
    LoadReport {
        url: url.to_string(),
        clients: logs.len(),
        connected: connected.len(),
        secs,
        subject_rate_hz: client_rate_hz.mean / subjects.len().max(1) as f64,
        subjects: subjects.into_iter().collect(),
        client_rate_hz: if rates.is_empty() {
            Spread::default()
        } else {
            client_rate_hz
        },
        latency_us: percentiles(&latencies),
        glass_us: glass_by_subject(logs),
        lagged: logs.iter().map(|l| l.lagged).sum(),
        missed_frames: logs.iter().map(|l| l.missed).sum(),
        errors: logs
            .iter()
            .filter_map(|l| l.error.clone())
            .take(5)
            .collect(),
    }
}

/// Capture-to-arrival percentiles of each subject over every client.
fn glass_by_subject(logs: &[ClientLog]) -> Vec<SubjectGlass> {
    let mut all: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
    for (subject, (_, v)) in logs.iter().flat_map(|l| l.glass.iter()) {
        all.entry(*subject).or_default().extend_from_slice(v);
    }
    all.into_iter()
        .map(|(subject, mut v)| {
            v.sort_unstable();
            SubjectGlass {
                subject,
                frames: v.len(),
                latency: percentiles(&v),
            }
        })
        .collect()
}

/// Percentiles of sorted samples (zeros when empty).
fn percentiles(sorted: &[u32]) -> Percentiles {
    let at = |q: f64| {
        if sorted.is_empty() {
            return 0;
        }
        let i = ((sorted.len() - 1) as f64 * q).round() as usize;
        sorted[i.min(sorted.len() - 1)]
    };
    Percentiles {
        p50: at(0.50),
        p90: at(0.90),
        p99: at(0.99),
        p999: at(0.999),
        max: sorted.last().copied().unwrap_or(0),
    }
}

fn print_report(r: &LoadReport) {
    println!(
        "{} of {} clients connected, {:.1} s measured, subjects {:?}",
        r.connected, r.clients, r.secs, r.subjects
    );
    println!(
        "rate per client: min {:.1} / mean {:.1} / max {:.1} Hz ({:.1} Hz per subject)",
        r.client_rate_hz.min, r.client_rate_hz.mean, r.client_rate_hz.max, r.subject_rate_hz
    );
    let ms = |us: u32| f64::from(us) / 1000.0;
    println!(
        "latency: p50 {:.2} ms, p90 {:.2} ms, p99 {:.2} ms, p99.9 {:.2} ms, max {:.2} ms",
        ms(r.latency_us.p50),
        ms(r.latency_us.p90),
        ms(r.latency_us.p99),
        ms(r.latency_us.p999),
        ms(r.latency_us.max)
    );
    for g in &r.glass_us {
        println!(
            "subject {}: capture to arrival p50 {:.2} ms, p99 {:.2} ms over {} new frames",
            g.subject,
            ms(g.latency.p50),
            ms(g.latency.p99),
            g.frames
        );
    }
    println!(
        "lagged notices: {}, missed frames: {}",
        r.lagged, r.missed_frames
    );
    for e in &r.errors {
        println!("error: {e}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_pick_the_ranked_samples() {
        let v: Vec<u32> = (1..=1000).collect();
        let p = percentiles(&v);
        assert_eq!((p.p50, p.p90, p.p99, p.max), (501, 900, 990, 1000));
        assert_eq!(percentiles(&[]), Percentiles::default());
    }

    #[test]
    fn a_client_that_never_connected_is_not_counted_as_connected() {
        let ok = ClientLog {
            frames: 120,
            latencies_us: vec![100; 120],
            subjects: [0, 1].into_iter().collect(),
            ..ClientLog::default()
        };
        let failed = ClientLog {
            error: Some("connect: refused".into()),
            ..ClientLog::default()
        };
        let r = summarise("ws://x", 1.0, &[ok, failed]);
        assert_eq!((r.clients, r.connected), (2, 1));
        assert_eq!(r.client_rate_hz.mean, 120.0);
        assert_eq!(r.subject_rate_hz, 60.0);
        assert_eq!(r.errors, vec!["connect: refused".to_string()]);
    }
}
