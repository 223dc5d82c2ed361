//! Real headless Chromium loads the web viewer from the real server.
//!
//! The server (in-process, 127.0.0.1:0) replays the embedded demo, plus the CMU walk from
//! ../shared/data when present, so two skeletons stand side by side. Chromium is driven over
//! the DevTools protocol (a WebSocket, so the test needs no extra crate): open `/`, wait for
//! frames, check that the page decoded them, that the skeletons move and that the WebGL canvas
//! has drawn something, then save a screenshot to target/viewer.png.
//!
//! Needs `chromium` (scripts/install-apps.sh installs it). Missing Chromium fails the test
//! with a clear message, unless RIGCAST_SKIP_APPS=1, which skips it with a printed reason.
#![allow(clippy::unwrap_used)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use rigcast_server::{ReplaySettings, ServerConfig, SourceSpec};
use serde_json::{json, Value};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The program's path, or None when absent and RIGCAST_SKIP_APPS=1 (panics otherwise).
fn find_app(name: &str) -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|dir| dir.join(name))
            .find(|p| p.is_file())
    });
    if found.is_none() {
        if std::env::var("RIGCAST_SKIP_APPS").as_deref() == Ok("1") {
            eprintln!("SKIP: `{name}` not found on PATH and RIGCAST_SKIP_APPS=1");
            return None;
        }
        panic!(
            "`{name}` not found on PATH: run scripts/install-apps.sh (or set RIGCAST_SKIP_APPS=1 to skip)"
        );
    }
    found
}

/// Kills Chromium even when an assertion fails half-way.
struct Browser {
    child: Child,
    profile: PathBuf,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

fn launch_chromium(chromium: &Path) -> (Browser, String) {
    let profile = std::env::temp_dir().join(format!("rigcast-chromium-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&profile);
    let mut child = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--hide-scrollbars",
            "--window-size=1280,800",
            "--remote-debugging-port=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("about:blank")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("chromium starts");
    let stderr = child.stderr.take().expect("piped stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    // Keep draining stderr for the whole run: a full pipe would stall Chromium.
    std::thread::spawn(move || {
        let mut sent = false;
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if !sent {
                if let Some(pos) = line.find("ws://") {
                    let _ = tx.send(line[pos..].trim().to_string());
                    sent = true;
                }
            }
        }
    });
    let browser = Browser { child, profile };
    let url = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("Chromium printed its DevTools address within 30 s");
    (browser, url)
}

type Cdp = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// A minimal DevTools client: numbered commands, events collected on the side.
struct DevTools {
    ws: Cdp,
    next_id: u64,
    session: Option<String>,
    events: Vec<Value>,
}

impl DevTools {
    async fn call(&mut self, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut message = json!({ "id": id, "method": method, "params": params });
        if let Some(session) = &self.session {
            message["sessionId"] = json!(session);
        }
        self.ws
            .send(Message::Text(message.to_string().into()))
            .await
            .expect("send to DevTools");
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            let next = tokio::time::timeout(remaining, self.ws.next())
                .await
                .unwrap_or_else(|_| panic!("DevTools did not answer {method} within 30 s"));
            let Some(Ok(Message::Text(text))) = next else {
                continue;
            };
            let value: Value = serde_json::from_str(text.as_str()).expect("DevTools JSON");
            if value["id"].as_u64() == Some(id) {
                assert!(
                    value.get("error").is_none(),
                    "{method} failed: {}",
                    value["error"]
                );
                return value["result"].clone();
            }
            if value.get("method").is_some() {
                self.events.push(value);
            }
        }
    }

    async fn eval(&mut self, expression: &str) -> Value {
        let result = self
            .call(
                "Runtime.evaluate",
                json!({ "expression": expression, "returnByValue": true }),
            )
            .await;
        assert!(
            result.get("exceptionDetails").is_none(),
            "page script `{expression}` threw: {}",
            result["exceptionDetails"]
        );
        result["result"]["value"].clone()
    }
}

fn base64_decode(text: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(text.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => continue, // padding and whitespace
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_shows_live_skeletons_in_chromium() {
    let Some(chromium) = find_app("chromium") else {
        return;
    };
    let mut sources = vec![SourceSpec::EmbeddedDemo];
    let walk = repo_root().join("../shared/data/bvh/cmu_131_01_walk.bvh");
    if walk.is_file() {
        sources.push(SourceSpec::ReplayFile {
            path: walk,
            name: Some("cmu_walk".into()),
            settings: ReplaySettings::default(),
        });
    } else {
        eprintln!("note: ../shared/data absent, showing the embedded demo only");
    }
    let num_subjects = sources.len();
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources,
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.expect("server starts");
    let page_url = format!("http://{}/", server.local_addr());

    let (browser, devtools_url) = launch_chromium(&chromium);
    let (ws, _) = tokio_tungstenite::connect_async(devtools_url.as_str())
        .await
        .expect("connect to DevTools");
    let mut cdp = DevTools {
        ws,
        next_id: 0,
        session: None,
        events: Vec::new(),
    };
    let target = cdp
        .call("Target.createTarget", json!({ "url": "about:blank" }))
        .await;
    let attached = cdp
        .call(
            "Target.attachToTarget",
            json!({ "targetId": target["targetId"], "flatten": true }),
        )
        .await;
    cdp.session = Some(attached["sessionId"].as_str().expect("session").to_string());
    cdp.call("Runtime.enable", json!({})).await;
    cdp.call("Log.enable", json!({})).await;
    cdp.call("Page.enable", json!({})).await;
    cdp.call(
        "Emulation.setDeviceMetricsOverride",
        json!({ "width": 1280, "height": 800, "deviceScaleFactor": 1, "mobile": false }),
    )
    .await;
    cdp.call("Page.navigate", json!({ "url": page_url })).await;

    // Frames arrive: the page shows its counter in the DOM and the title.
    let start = Instant::now();
    let mut frames = 0;
    while start.elapsed() < Duration::from_secs(20) {
        let value = cdp
            .eval("Number(document.getElementById('frame-count')?.dataset.frames ?? 0)")
            .await;
        frames = value.as_u64().unwrap_or(0);
        if frames >= 60 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    assert!(
        frames >= 60,
        "viewer counted only {frames} frames in 20 s; page events: {:?}",
        cdp.events
    );

    // Let the graph fill and the skeletons walk, then check that they move.
    let pose_probe = "JSON.stringify([...window.rigcast.views.values()].map(v => v.worldP.map(p => [p.x, p.y, p.z])))";
    let before: Vec<Vec<[f64; 3]>> =
        serde_json::from_str(cdp.eval(pose_probe).await.as_str().unwrap()).unwrap();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let after: Vec<Vec<[f64; 3]>> =
        serde_json::from_str(cdp.eval(pose_probe).await.as_str().unwrap()).unwrap();
    assert_eq!(before.len(), num_subjects, "one 3D skeleton per subject");
    for (i, (a, b)) in before.iter().zip(&after).enumerate() {
        let moved = a
            .iter()
            .zip(b)
            .map(|(p, q)| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        assert!(moved > 0.01, "skeleton {i} did not move ({moved} m)");
    }

    let summary = cdp
        .eval(
            "JSON.stringify({ frames: window.rigcast.framesReceived, drawn: window.rigcast.framesDrawn, \
              title: document.title, connection: document.getElementById('connection').textContent, \
              subjects: document.querySelectorAll('#subjects li').length, \
              labels: [...document.querySelectorAll('.label')].filter(l => l.style.display !== 'none').map(l => l.textContent), \
              rates: [...window.rigcast.stats.values()].map(s => s.arrivals.length), \
              badFrames: window.rigcast.stream.badFrames })",
        )
        .await;
    let summary: Value = serde_json::from_str(summary.as_str().unwrap()).unwrap();
    println!("viewer: {summary}");
    assert_eq!(summary["connection"], "connected");
    assert_eq!(summary["subjects"].as_u64(), Some(num_subjects as u64));
    assert_eq!(summary["badFrames"], 0);
    assert!(summary["title"].as_str().unwrap().contains("frames"));
    let labels: Vec<&str> = summary["labels"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| l.as_str())
        .collect();
    assert!(
        labels.iter().any(|l| l.starts_with("demo")),
        "subject label missing: {labels:?}"
    );
    assert!(
        labels.len() > 3 * num_subjects,
        "bone labels missing: {labels:?}"
    );
    for rate in summary["rates"].as_array().unwrap() {
        assert!(
            rate.as_u64().unwrap() >= 20,
            "page receives {rate} frames/s"
        );
    }

    // The WebGL canvas really drew the skeletons: count pixels away from the background.
    let lit = cdp
        .eval(
            "(() => { const c = document.getElementById('scene'); const t = document.createElement('canvas'); \
              t.width = c.width; t.height = c.height; const g = t.getContext('2d'); g.drawImage(c, 0, 0); \
              const d = g.getImageData(0, 0, t.width, t.height).data; let n = 0; \
              for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x15) + Math.abs(d[i+1] - 0x17) + Math.abs(d[i+2] - 0x1c) > 60) n++; \
              return n; })()",
        )
        .await
        .as_u64()
        .unwrap_or(0);
    assert!(lit > 500, "the 3D view drew only {lit} bright pixels");

    let exceptions: Vec<&Value> = cdp
        .events
        .iter()
        .filter(|e| e["method"] == "Runtime.exceptionThrown")
        .collect();
    assert!(exceptions.is_empty(), "page threw: {exceptions:?}");
    let failed_loads: Vec<&Value> = cdp
        .events
        .iter()
        .filter(|e| e["method"] == "Log.entryAdded" && e["params"]["entry"]["level"] == "error")
        .collect();
    assert!(
        failed_loads.is_empty(),
        "page logged errors: {failed_loads:?}"
    );

    let shot = cdp
        .call("Page.captureScreenshot", json!({ "format": "png" }))
        .await;
    let png = base64_decode(shot["data"].as_str().expect("screenshot data"));
    assert!(png.starts_with(b"\x89PNG"), "screenshot is not a PNG");
    let out = repo_root().join("target").join("viewer.png");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    std::fs::write(&out, &png).unwrap();
    println!("screenshot: {} ({} bytes)", out.display(), png.len());

    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
}
