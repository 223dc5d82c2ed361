//! Headless Chromium driven over the DevTools protocol (a WebSocket, so no extra crate): the
//! browser process, a minimal DevTools client, and base64 for screenshots. Shared by the
//! viewer tests.
#![allow(clippy::unwrap_used)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::{json, Value};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

/// Kills Chromium even when an assertion fails half-way.
pub struct Browser {
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

pub fn launch_chromium(chromium: &Path) -> (Browser, String) {
    // Several browsers of one test process must not share a profile (Chromium refuses).
    static LAUNCHES: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = LAUNCHES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let profile = std::env::temp_dir().join(format!("rigcast-chromium-{}-{n}", std::process::id()));
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

/// The DevTools connection.
pub type Cdp = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// A minimal DevTools client: numbered commands, events collected on the side.
pub struct DevTools {
    /// The DevTools WebSocket.
    pub ws: Cdp,
    /// Last command id used.
    pub next_id: u64,
    /// The page session commands go to (flattened sessions).
    pub session: Option<String>,
    /// Events received while waiting for answers.
    pub events: Vec<Value>,
}

impl DevTools {
    /// Sends one command and waits for its answer (30 s).
    pub async fn call(&mut self, method: &str, params: Value) -> Value {
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

    /// Evaluates an expression in the page; panics when it throws.
    pub async fn eval(&mut self, expression: &str) -> Value {
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

/// Decodes standard base64 (screenshots).
pub fn base64_decode(text: &str) -> Vec<u8> {
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

impl DevTools {
    /// Evaluates an expression that returns `JSON.stringify(...)` and parses it.
    pub async fn eval_json(&mut self, expression: &str) -> Value {
        let text = self.eval(expression).await;
        serde_json::from_str(text.as_str().expect("a JSON string")).expect("page JSON")
    }

    /// The largest change of subject `id`'s first skinned mesh's bone matrices over 0.7 s
    /// (the viewer's `rigcast.meshes()`): non-zero while the stream drives the skin.
    pub async fn bone_matrices_move(&mut self, id: u32) -> f64 {
        let probe = format!("JSON.stringify(window.rigcast.meshes()[{id}].boneMatrices)");
        let a = self.eval_json(&probe).await;
        tokio::time::sleep(std::time::Duration::from_millis(700)).await;
        let b = self.eval_json(&probe).await;
        a.as_array()
            .unwrap()
            .iter()
            .zip(b.as_array().unwrap())
            .map(|(x, y)| (x.as_f64().unwrap() - y.as_f64().unwrap()).abs())
            .fold(0.0, f64::max)
    }
}

impl DevTools {
    /// Launches Chromium, opens one 1280×800 page with Runtime, Log and Page events enabled
    /// and navigates it to `url`.
    pub async fn open(chromium: &Path, url: &str) -> (Browser, DevTools) {
        let (browser, devtools_url) = launch_chromium(chromium);
        let (ws, _) = tokio_tungstenite::connect_async(devtools_url.as_str())
            .await
            .expect("connect to DevTools");
        let mut cdp = DevTools {
            ws,
            next_id: 0,
            session: None,
            events: Vec::new(),
        };
        let page = cdp
            .call("Target.createTarget", json!({ "url": "about:blank" }))
            .await;
        let attached = cdp
            .call(
                "Target.attachToTarget",
                json!({ "targetId": page["targetId"], "flatten": true }),
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
        cdp.call("Page.navigate", json!({ "url": url })).await;
        (browser, cdp)
    }

    /// [`DevTools::open`] on the viewer that the server at `addr` serves.
    pub async fn open_viewer(chromium: &Path, addr: std::net::SocketAddr) -> (Browser, DevTools) {
        DevTools::open(chromium, &format!("http://{addr}/")).await
    }

    /// The demo server (`start_demo_server`) and [`DevTools::open_viewer`] on its viewer.
    pub async fn open_demo(chromium: &Path) -> (rigcast_server::ServerHandle, Browser, DevTools) {
        let server = crate::start_demo_server().await;
        let (browser, cdp) = DevTools::open_viewer(chromium, server.local_addr()).await;
        (server, browser, cdp)
    }

    /// Evaluates `expression` every `poll` until it is `true`; false when `timeout` passes
    /// first.
    pub async fn wait_true(
        &mut self,
        expression: &str,
        timeout: std::time::Duration,
        poll: std::time::Duration,
    ) -> bool {
        let start = std::time::Instant::now();
        loop {
            if self.eval(expression).await == true {
                return true;
            }
            if start.elapsed() >= timeout {
                return false;
            }
            tokio::time::sleep(poll).await;
        }
    }

    /// Evaluates `expression` (a `JSON.stringify(...)`) every `poll` until `done` holds for its
    /// value or `timeout` passes; the last value.
    pub async fn poll_json(
        &mut self,
        expression: &str,
        timeout: std::time::Duration,
        poll: std::time::Duration,
        done: impl Fn(&Value) -> bool,
    ) -> Value {
        let start = std::time::Instant::now();
        let mut value = Value::Null;
        while start.elapsed() < timeout {
            value = self.eval_json(expression).await;
            if done(&value) {
                break;
            }
            tokio::time::sleep(poll).await;
        }
        value
    }

    /// A PNG screenshot of the page.
    pub async fn screenshot(&mut self) -> Vec<u8> {
        let shot = self
            .call("Page.captureScreenshot", json!({ "format": "png" }))
            .await;
        let png = base64_decode(shot["data"].as_str().expect("screenshot data"));
        assert!(png.starts_with(b"\x89PNG"), "screenshot is not a PNG");
        png
    }

    /// Page exceptions seen so far.
    pub fn thrown(&self) -> Vec<&Value> {
        self.events
            .iter()
            .filter(|e| e["method"] == "Runtime.exceptionThrown")
            .collect()
    }

    /// Page exceptions and error-level log entries seen so far.
    pub fn errors(&self) -> Vec<&Value> {
        self.events
            .iter()
            .filter(|e| {
                e["method"] == "Runtime.exceptionThrown"
                    || (e["method"] == "Log.entryAdded" && e["params"]["entry"]["level"] == "error")
            })
            .collect()
    }
}

/// One browser at a time in a test binary: the frame rates a test measures must not compete
/// with another browser of the same file.
static ONE_BROWSER: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// Chromium (or `None`, with a printed reason, when it is not installed) and the test binary's
/// one-browser lock, held as long as the guard lives.
pub async fn one_browser() -> Option<(PathBuf, tokio::sync::MutexGuard<'static, ()>)> {
    let chromium = crate::find_app("chromium")?;
    Some((chromium, ONE_BROWSER.lock().await))
}
