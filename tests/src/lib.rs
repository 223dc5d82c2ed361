//! End-to-end test helpers shared by the tests in `tests/tests/`: a WebSocket client that
//! speaks the rigcast protocol, fixtures built in code, and the path to shared test data.
#![allow(clippy::unwrap_used)]

pub mod chromium;
pub mod coverage;
pub mod fuzz;
pub mod nats;
pub mod skinned;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use glam::{Quat, Vec3};
use rigcast_protocol::frame::{decode_frame, DecodedFrame};
use rigcast_protocol::ServerMessage;
use rigcast_retarget::{Clip, Pose, RawSkeleton, Skeleton, Transform};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

/// A connected WebSocket client.
pub type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// What arrived on the stream.
#[derive(Debug)]
pub enum Incoming {
    /// A JSON control message.
    Json(ServerMessage),
    /// A binary frame, with the local receive time (Unix ns).
    Frame(DecodedFrame, u64),
}

/// Sends `pose` (bones named `names`, in order) as one VMC packet set stamped `t`, the way a
/// VMC performer application does.
pub fn send_vmc_pose(
    socket: &std::net::UdpSocket,
    to: std::net::SocketAddr,
    enc: &mut rigcast_protocol::vmc::VmcEncoder,
    names: &[String],
    pose: &Pose,
    t: f32,
) {
    for bundle in enc.encode(t, vmc_bones(names, pose)) {
        socket.send_to(bundle, to).unwrap();
    }
}

/// `pose`'s bones as VMC bones named `names` (in order), for an encoder.
pub fn vmc_bones<'a>(
    names: &'a [String],
    pose: &'a Pose,
) -> impl Iterator<Item = rigcast_protocol::vmc::VmcBone<'a>> {
    names
        .iter()
        .zip(&pose.translations)
        .zip(&pose.rotations)
        .map(
            |((name, &translation), &rotation)| rigcast_protocol::vmc::VmcBone {
                name,
                translation,
                rotation,
            },
        )
}

/// Unix epoch nanoseconds.
pub fn unix_nanos() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64
}

/// Connects to `ws://addr/v1/stream`.
pub async fn connect(url: &str) -> Ws {
    let (ws, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    ws
}

/// Reads the next protocol message (skipping WebSocket control frames), with a timeout.
pub async fn next(ws: &mut Ws, timeout: Duration) -> Option<Incoming> {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.checked_duration_since(Instant::now())?;
        let msg = tokio::time::timeout(left, ws.next()).await.ok()??.unwrap();
        match msg {
            Message::Text(t) => {
                let m: ServerMessage = serde_json::from_str(t.as_str())
                    .unwrap_or_else(|e| panic!("undecodable server JSON {t}: {e}"));
                return Some(Incoming::Json(m));
            }
            Message::Binary(b) => {
                let now = unix_nanos();
                return Some(Incoming::Frame(decode_frame(&b).unwrap(), now));
            }
            Message::Close(_) => return None,
            _ => {}
        }
    }
}

/// Sends a text message.
pub async fn send_text(ws: &mut Ws, text: &str) {
    ws.send(Message::text(text.to_string())).await.unwrap();
}

/// Waits for the next JSON message, skipping frames.
pub async fn next_json(ws: &mut Ws, timeout: Duration) -> Option<ServerMessage> {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.checked_duration_since(Instant::now())?;
        match next(ws, left).await? {
            Incoming::Json(m) => return Some(m),
            Incoming::Frame(..) => {}
        }
    }
}

/// Reads `hello` and one `skeleton` per subject.
pub async fn handshake(ws: &mut Ws) -> (ServerMessage, Vec<ServerMessage>) {
    let hello = next_json(ws, Duration::from_secs(5)).await.expect("hello");
    let ServerMessage::Hello { subjects, .. } = &hello else {
        panic!("expected hello, got {hello:?}");
    };
    let mut skeletons = Vec::new();
    for _ in 0..subjects.len() {
        let s = next_json(ws, Duration::from_secs(5))
            .await
            .expect("skeleton");
        assert!(matches!(s, ServerMessage::Skeleton { .. }), "{s:?}");
        skeletons.push(s);
    }
    (hello, skeletons)
}

/// Collects frames for `duration`; returns them with their receive times.
pub async fn collect_frames(ws: &mut Ws, duration: Duration) -> Vec<(DecodedFrame, u64)> {
    let deadline = Instant::now() + duration;
    let mut out = Vec::new();
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match next(ws, left).await {
            Some(Incoming::Frame(f, t)) => out.push((f, t)),
            Some(Incoming::Json(_)) => {}
            None => break,
        }
    }
    out
}

/// Frames until `wanted` have arrived or `timeout` passed: for tests that need a count of
/// frames, which a loaded machine delivers later but still delivers.
pub async fn collect_n_frames(
    ws: &mut Ws,
    wanted: usize,
    timeout: Duration,
) -> Vec<(DecodedFrame, u64)> {
    let deadline = Instant::now() + timeout;
    let mut out = Vec::new();
    while out.len() < wanted {
        let Some(left) = deadline.checked_duration_since(Instant::now()) else {
            break;
        };
        match next(ws, left).await {
            Some(Incoming::Frame(f, t)) => out.push((f, t)),
            Some(Incoming::Json(_)) => {}
            None => break,
        }
    }
    out
}

/// A WebSocket upgrade on a socket with a tiny receive buffer, read up to the end of the 101
/// head only, so the socket fills as soon as the client stops reading.
pub async fn stalled_client(addr: std::net::SocketAddr) -> TcpStream {
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut raw = socket.connect(addr).await.unwrap();
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    raw.write_all(
        b"GET /v1/stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
          Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n",
    )
    .await
    .unwrap();
    let mut head = Vec::new();
    while !head.ends_with(b"\r\n\r\n") {
        head.push(raw.read_u8().await.unwrap());
    }
    assert!(head.starts_with(b"HTTP/1.1 101"));
    raw
}

/// An idle graph of every labelled human clip in the shared data's `bvh/` folder (found by
/// listing it and reading the label files; clip paths absolute) written into the temporary
/// file `file_name` (`.rmg`), and the clips; `None` (with a printed reason) when fewer than two
/// are there.
pub fn build_idle_graph(file_name: &str) -> Option<(PathBuf, Vec<Clip>)> {
    let root = shared_data_dir("bvh", "the shared BVH clips")?;
    let labels = all_labels(&root);
    let human = |p: &std::path::Path| {
        let key = p.strip_prefix(&root).ok()?.to_str()?.replace('\\', "/");
        Some(labels.get(&key)?.get("kind")?.as_str()? == "human")
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(root.join("bvh"))
        .ok()?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("bvh")))
        .filter(|p| human(p) == Some(true))
        .collect();
    paths.sort();
    if paths.len() < 2 {
        println!(
            "SKIP: fewer than two labelled human clips in {}",
            root.join("bvh").display()
        );
        return None;
    }
    let clips: Vec<Clip> = paths
        .iter()
        .map(|p| rigcast_sources::load_clip(p).unwrap())
        .collect();
    let mut graph = rigcast_retarget::graph::MotionGraph::build(
        &clips,
        rigcast_retarget::graph::GraphSettings::default(),
        &mut |_| {},
    )
    .unwrap();
    for (c, p) in graph.clips.iter_mut().zip(&paths) {
        c.path = Some(std::fs::canonicalize(p).unwrap().display().to_string());
    }
    let file = temp_path(file_name);
    std::fs::write(&file, graph.to_json()).unwrap();
    println!(
        "graph: {} nodes, {} kept, {} transitions",
        graph.num_frames(),
        graph.num_kept(),
        graph.transitions.len()
    );
    Some((file, clips))
}

/// The numbers of a JSON array (panics on anything else: a test's expectation).
pub fn f64s(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .expect("a JSON array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

#[path = "../../sources/tests/common/shared_data.rs"]
mod shared_data;
pub use shared_data::{
    all_labels, first_in_place_cycle, first_neckless_clip, first_walk, first_walks, gltf_json,
    human_rigs, labelled, labelled_where, shared_clip, shared_data, shared_data_all,
    shared_data_dir, skinned_human_glbs, travelling_clips, walks, Gait, Labelled, CMU_WALK,
};

/// A 6-bone creature with a tail, animated with distinct rotations on every bone: 48 frames at
/// 30 fps. Built in code so tests do not depend on any file.
pub fn fixture_clip() -> Clip {
    let mut raw = RawSkeleton::default();
    let t = |x: f32, y: f32, z: f32| Transform::from_translation(Vec3::new(x, y, z));
    let root = raw.add("root", None, t(0.0, 1.0, 0.0));
    let body = raw.add("body", Some(root), t(0.0, 0.2, 0.1));
    let head = raw.add("head", Some(body), t(0.0, 0.3, 0.2));
    raw.add("jaw", Some(head), t(0.0, -0.05, 0.1));
    let tail = raw.add("tail1", Some(root), t(0.0, 0.0, -0.3));
    raw.add("tail2", Some(tail), t(0.0, 0.0, -0.3));
    let skeleton = Arc::new(Skeleton::build(&raw).unwrap());
    let n = 48;
    let poses = (0..n)
        .map(|i| {
            let a = i as f32 / n as f32 * std::f32::consts::TAU;
            let mut p = Pose::from_rest(&skeleton);
            for (b, q) in p.rotations.iter_mut().enumerate() {
                let k = b as f32 + 1.0;
                *q = Quat::from_euler(
                    glam::EulerRot::YXZ,
                    0.5 * (a + k).sin(),
                    0.3 * (2.0 * a - k).cos(),
                    0.2 * (a * k).sin(),
                );
            }
            p.translations[0] = Vec3::new(0.2 * a.sin(), 1.0, 0.1 * a.cos());
            p
        })
        .collect();
    Clip::new("fixture", skeleton, poses, 1.0 / 30.0).unwrap()
}

/// Largest angle (radians) between the frame's rotations and those of the clip frame that
/// matches best; returns (clip frame index, angle).
pub fn best_matching_frame(clip: &Clip, rotations: &[Quat]) -> (usize, f32) {
    let mut best = (usize::MAX, f32::MAX);
    for (i, pose) in clip.poses.iter().enumerate() {
        let worst = pose
            .rotations
            .iter()
            .zip(rotations)
            .map(|(&a, &b)| rotation_angle(a, b))
            .fold(0.0f32, f32::max);
        if worst < best.1 {
            best = (i, worst);
        }
    }
    best
}

/// Whether a measured rate fits a configured one on a shared, loaded machine: never above it
/// (a server cannot tick faster than asked; 10% covers timer jitter over a short window), and
/// not below 60% of it (the tick skips missed ticks when starved of CPU, so a loaded 2-core
/// machine legitimately runs slow, but a halved rate is still a failure).
pub fn rate_plausible(measured_hz: f64, configured_hz: f64) -> bool {
    measured_hz <= configured_hz * 1.1 && measured_hz >= configured_hz * 0.6
}

/// Frames per second from receive times (first to last).
pub fn measured_rate(frames: &[(DecodedFrame, u64)]) -> f64 {
    if frames.len() < 2 {
        return 0.0;
    }
    let span = (frames[frames.len() - 1].1 - frames[0].1) as f64 * 1e-9;
    (frames.len() - 1) as f64 / span
}

/// Angle in radians between two rotations (q ≡ -q), accurate for tiny differences: computed
/// from the chord length in f64 rather than `acos` of a dot product, which in f32 cannot
/// resolve angles below ~1e-3.
pub fn rotation_angle(a: Quat, b: Quat) -> f32 {
    let a = glam::Vec4::from(a).as_dvec4();
    let b = glam::Vec4::from(b).as_dvec4();
    let chord = (a - b).length().min((a + b).length());
    (4.0 * (chord / 2.0).min(1.0).asin()) as f32
}

/// Starts an in-process server on 127.0.0.1:0.
pub async fn start_server(
    sources: Vec<rigcast_server::SourceSpec>,
    rate_hz: f64,
    vmc_out: Vec<String>,
) -> rigcast_server::ServerHandle {
    let config = rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz,
        sources,
        vmc_out: vmc_out.iter().map(|v| v.parse().unwrap()).collect(),
        ..rigcast_server::ServerConfig::default()
    };
    rigcast_server::start(config).await.unwrap()
}

/// Sends `raw` bytes to the HTTP listener and reads until the server closes the connection
/// (the server always answers with `Connection: close`). Returns the response, lossily as
/// text, or `None` when the server reset the connection before anything arrived. Panics
/// after `timeout`: a request the server never finishes is a hang.
pub async fn http_raw(addr: std::net::SocketAddr, raw: &[u8], timeout: Duration) -> Option<String> {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let exchange = async {
        let mut s = TcpStream::connect(addr).await.unwrap();
        // A write error means the server already answered and closed (e.g. an oversized head).
        let _ = s.write_all(raw).await;
        let mut out = Vec::new();
        let mut chunk = [0u8; 4096];
        loop {
            match s.read(&mut chunk).await {
                Ok(0) => break,
                Ok(n) => out.extend_from_slice(&chunk[..n]),
                Err(_) if !out.is_empty() => break,
                Err(_) => return None,
            }
        }
        Some(String::from_utf8_lossy(&out).into_owned())
    };
    tokio::time::timeout(timeout, exchange)
        .await
        .unwrap_or_else(|_| panic!("no complete HTTP answer within {timeout:?}"))
}

/// `GET path` over HTTP/1.1: (head, body).
pub async fn http_get(addr: std::net::SocketAddr, path: &str) -> (String, String) {
    let request = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    let text = http_raw(addr, request.as_bytes(), Duration::from_secs(10))
        .await
        .unwrap_or_else(|| panic!("GET {path}: connection reset"));
    let (head, body) = text
        .split_once("\r\n\r\n")
        .unwrap_or_else(|| panic!("GET {path}: no response head in {text:?}"));
    (head.to_string(), body.to_string())
}

/// A chain of `bones` bones `spacing` apart (up +Y), each turning a little about Z per frame
/// (`step` × frame × (bone + 1) radians) over `frames` frames at `fps`: a clip of a chosen
/// frame size (60 + 16 × bones bytes on the wire) for the fan-out and limits tests.
pub fn chain_clip(bones: usize, frames: usize, spacing: f32, step: f32, fps: f64) -> Clip {
    let mut raw = RawSkeleton::default();
    let mut parent = None;
    for i in 0..bones {
        parent = Some(raw.add(
            format!("b{i}"),
            parent,
            Transform::from_translation(Vec3::Y * spacing),
        ));
    }
    let skeleton = Arc::new(Skeleton::build(&raw).unwrap());
    let poses = (0..frames)
        .map(|f| {
            let mut p = Pose::from_rest(&skeleton);
            for (i, q) in p.rotations.iter_mut().enumerate() {
                *q = Quat::from_rotation_z(step * (f * (i + 1)) as f32);
            }
            p
        })
        .collect();
    Clip::new("chain", skeleton, poses, 1.0 / fps).unwrap()
}

/// A VMC input on a free loopback port, subject "performer", lost after `lost_after_secs`
/// of silence: the live source of the end-to-end VMC tests.
pub fn vmc_performer(lost_after_secs: f32) -> rigcast_server::SourceSpec {
    rigcast_server::SourceSpec::Vmc(rigcast_server::config::VmcSpec {
        lost_after_secs: Some(lost_after_secs),
        name: Some("performer".into()),
        ..rigcast_server::config::VmcSpec::loopback(0)
    })
}

/// A replay of an in-memory clip, looping from the start at normal speed.
pub fn clip_source(clip: Clip) -> rigcast_server::SourceSpec {
    rigcast_server::SourceSpec::ReplayClip(rigcast_server::config::ReplayClipSpec {
        clip,
        name: None,
        settings: rigcast_server::ReplaySettings::default(),
    })
}

/// A unique temporary path (no tempfile crate: pid + name + counter).
pub fn temp_path(name: &str) -> PathBuf {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "rigcast-tests-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    // Each call gets its own folder; one left by an earlier process with the same id (ids are
    // reused) is stale and must not leak into this test (a stale token file, a stale cache).
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

// -- real-program tests (Blender, Chromium, the `rigcast` binary) ---------------------------

/// The repository root (the parent of `tests/`).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// A program's path on PATH, or None when it is absent and RIGCAST_SKIP_APPS=1. Panics
/// otherwise: a real-program test must not pass silently on a machine without the program.
pub fn find_app(name: &str) -> Option<PathBuf> {
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

/// Starts an in-process server exactly as `rigcast serve` without arguments would (the bundled
/// walk `demo` and the built-in `mannequin` retargeted from it), but on 127.0.0.1:0.
/// Starts `config` listening on 127.0.0.1:0 with one VMC source ([`vmc_performer`], lost
/// after 0.25 s) as subject 0: the server, and the address to send VMC to.
pub async fn start_vmc_server(
    config: rigcast_server::ServerConfig,
) -> (rigcast_server::ServerHandle, std::net::SocketAddr) {
    let config = rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![vmc_performer(0.25)],
        ..config
    };
    let server = rigcast_server::start(config).await.unwrap();
    let vmc_port = server.state().subjects()[0].listen_addr.unwrap().port();
    let to = format!("127.0.0.1:{vmc_port}").parse().unwrap();
    (server, to)
}

pub async fn start_demo_server() -> rigcast_server::ServerHandle {
    let config = rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        ..rigcast_server::ServerConfig::default()
    };
    rigcast_server::start(config).await.unwrap()
}

/// A TCP port that was free a moment ago on 127.0.0.1 (for programs that need a fixed
/// `--listen` address; the tiny race with other processes is accepted in tests).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A child process killed (and reaped) on drop, so a failing assertion never leaks it.
pub struct KillOnDrop(pub std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The `rigcast` binary of this build. `cargo test -p rigcast-tests` does not build other
/// packages' binaries, so this runs `cargo build` for it (same profile and target dir; a
/// no-op when it is up to date).
pub fn rigcast_binary() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    // target/<profile>/deps/<test> -> target/<profile>/rigcast
    let profile_dir = exe.parent().and_then(|d| d.parent()).unwrap().to_path_buf();
    let bin = profile_dir.join(format!("rigcast{}", std::env::consts::EXE_SUFFIX));
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = std::process::Command::new(cargo);
    cmd.args(["build", "-p", "rigcast-server", "--bin", "rigcast"])
        .current_dir(repo_root());
    if profile_dir.file_name().is_some_and(|n| n == "release") {
        cmd.arg("--release");
    }
    if let Some(target_dir) = profile_dir.parent() {
        cmd.env("CARGO_TARGET_DIR", target_dir);
    }
    let status = cmd.status().expect("cargo runs");
    assert!(status.success(), "building the rigcast binary failed");
    assert!(bin.is_file(), "no binary at {}", bin.display());
    bin
}

/// A `rigcast serve` process of this build on a free loopback port, with its own config
/// folder (so its control token is its own), its stdout collected line by line.
pub struct ServeProcess {
    /// The process (killed on drop).
    pub child: KillOnDrop,
    /// Where it listens.
    pub addr: std::net::SocketAddr,
    /// Its `XDG_CONFIG_HOME`.
    pub config_home: PathBuf,
    lines: Arc<std::sync::Mutex<Vec<String>>>,
}

impl ServeProcess {
    /// Starts `rigcast serve --listen 127.0.0.1:PORT ARGS` and waits (≤ 60 s) until it prints
    /// its connection cap (the last line of its access report). `max_open_files` sets the
    /// process's RLIMIT_NOFILE (soft and hard) before it starts, like `ulimit -n`.
    pub fn start(args: &[&str], config_home: PathBuf, max_open_files: Option<u64>) -> ServeProcess {
        let listen = format!("127.0.0.1:{}", free_port());
        Self::start_on(&listen, args, config_home, max_open_files)
    }

    /// [`ServeProcess::start`] on a given `--listen` address (port 0 allowed: the printed
    /// stream address tells the real one).
    pub fn start_on(
        listen: &str,
        args: &[&str],
        config_home: PathBuf,
        max_open_files: Option<u64>,
    ) -> ServeProcess {
        use std::io::BufRead;
        use std::os::unix::process::CommandExt;
        let mut cmd = std::process::Command::new(rigcast_binary());
        cmd.args(["serve", "--listen", listen])
            .args(args)
            .env("XDG_CONFIG_HOME", &config_home)
            // Its own mapping cache too: a test's set_mapping overrides are kept in the cache
            // (by design, they survive restarts) and must not reach other tests' servers.
            .env("XDG_CACHE_HOME", config_home.join("cache"))
            .env_remove("RIGCAST_CACHE_DIR")
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped());
        if let Some(n) = max_open_files {
            // SAFETY: only setrlimit (async-signal-safe) runs between fork and exec.
            unsafe {
                cmd.pre_exec(move || {
                    let lim = libc::rlimit {
                        rlim_cur: n,
                        rlim_max: n,
                    };
                    if libc::setrlimit(libc::RLIMIT_NOFILE, &lim) != 0 {
                        return Err(std::io::Error::last_os_error());
                    }
                    Ok(())
                });
            }
        }
        let mut child = cmd.spawn().expect("rigcast starts");
        let lines = Arc::new(std::sync::Mutex::new(Vec::new()));
        let (tx, rx) = std::sync::mpsc::channel();
        for (pipe, prefix) in [
            (
                Box::new(child.stdout.take().unwrap()) as Box<dyn std::io::Read + Send>,
                "",
            ),
            (Box::new(child.stderr.take().unwrap()), "stderr: "),
        ] {
            let lines = lines.clone();
            let tx = tx.clone();
            std::thread::spawn(move || {
                for line in std::io::BufReader::new(pipe).lines().map_while(Result::ok) {
                    let cap = line.trim().starts_with("connections: ");
                    // Stored before the start is signalled, so the caller sees this line.
                    lines.lock().unwrap().push(format!("{prefix}{line}"));
                    if cap {
                        let _ = tx.send(());
                    }
                }
            });
        }
        let child = KillOnDrop(child);
        if rx.recv_timeout(Duration::from_secs(60)).is_err() {
            panic!(
                "rigcast did not report its connection cap within 60 s: {:?}",
                lines.lock().unwrap()
            );
        }
        let stream_line = lines
            .lock()
            .unwrap()
            .iter()
            .find_map(|l| l.trim().strip_prefix("stream: ws://").map(str::to_string))
            .expect("stream address printed");
        let addr = stream_line
            .trim_end_matches("/v1/stream")
            .parse()
            .expect("a socket address");
        ServeProcess {
            child,
            addr,
            config_home,
            lines,
        }
    }

    /// Everything printed so far (stderr lines prefixed `stderr: `).
    pub fn output(&self) -> Vec<String> {
        self.lines.lock().unwrap().clone()
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.0.id()
    }

    /// Resident memory of the process (VmRSS), KiB.
    pub fn rss_kib(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).unwrap();
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .expect("VmRSS in /proc/PID/status")
    }
}

/// World positions of every bone of a version 2 frame, by forward kinematics of the wire
/// skeleton: the client's own computation, independent of the server's.
pub fn wire_fk(
    bones: &[rigcast_protocol::control::BoneInfo],
    frame: &rigcast_protocol::frame::DecodedFrame,
) -> Vec<glam::Vec3> {
    let mut slot = 0;
    chain_positions(bones, |i, bone| {
        let translation = if bone.translated {
            slot += 1;
            frame.translations[slot - 1]
        } else {
            glam::Vec3::from(bone.rest_translation)
        };
        (frame.rotations[i], translation)
    })
}

/// Rest world positions of the wire skeleton (its rest rotations and translations).
pub fn wire_rest_positions(bones: &[rigcast_protocol::control::BoneInfo]) -> Vec<glam::Vec3> {
    chain_positions(bones, |_, b| {
        (
            glam::Quat::from_array(b.rest_rotation),
            glam::Vec3::from(b.rest_translation),
        )
    })
}

/// World positions down the wire skeleton's parent chain, given each bone's local rotation
/// and translation (parents come before children in the list).
fn chain_positions(
    bones: &[rigcast_protocol::control::BoneInfo],
    mut local: impl FnMut(usize, &rigcast_protocol::control::BoneInfo) -> (glam::Quat, glam::Vec3),
) -> Vec<glam::Vec3> {
    let mut world: Vec<(glam::Quat, glam::Vec3)> = Vec::with_capacity(bones.len());
    for (i, bone) in bones.iter().enumerate() {
        let (rotation, translation) = local(i, bone);
        world.push(match bone.parent {
            None => (rotation, translation),
            Some(p) => {
                let (pr, pp) = world[p as usize];
                (pr * rotation, pp + pr * translation)
            }
        });
    }
    world.into_iter().map(|(_, p)| p).collect()
}

/// What a version 2 client of one subject saw: its skeleton, its frames in arrival order
/// (with receive times), and the other JSON messages.
pub struct SubjectStream {
    pub bones: Option<Vec<rigcast_protocol::control::BoneInfo>>,
    pub frames: Vec<(DecodedFrame, u64)>,
    pub messages: Vec<ServerMessage>,
}

/// Asks `ws` for version 2 frames and watches `subject` for `span` (or until the stream
/// closes).
pub async fn watch_v2(ws: &mut Ws, subject: u32, span: Duration) -> SubjectStream {
    send_text(ws, r#"{"type":"set_protocol","version":2}"#).await;
    let mut seen = SubjectStream {
        bones: None,
        frames: Vec::new(),
        messages: Vec::new(),
    };
    let t0 = Instant::now();
    while let Some(left) = span.checked_sub(t0.elapsed()) {
        match next(ws, left).await {
            Some(Incoming::Json(ServerMessage::Skeleton {
                subject: s, bones, ..
            })) if s == subject => seen.bones = Some(bones),
            Some(Incoming::Json(m)) => seen.messages.push(m),
            Some(Incoming::Frame(f, at)) if f.header.subject == subject && f.version == 2 => {
                seen.frames.push((f, at));
            }
            Some(_) => {}
            None => break,
        }
    }
    seen
}

/// What a subject's `footplants` messages show against its version 2 frames (judged with the
/// client's own FK; see [`judge_footplants`]).
pub struct PlantWatch {
    /// `footplants` messages of the subject.
    pub messages: usize,
    /// Messages whose frame was received (each foot's position checked against FK).
    pub checked: usize,
    /// (bone, planted) states seen.
    pub seen: std::collections::HashSet<(String, bool)>,
    /// Farthest the joint a planted foot stands on moved horizontally over one plant (m, along
    /// its path), and per frame (m).
    pub planted_travel: f32,
    pub planted_drift: f32,
    /// Plants long enough to be judged.
    pub planted_judged: usize,
    /// Farthest a lifted foot moved over one message's span (m).
    pub lifted_travel: f32,
}

/// A landing foot is eased onto its pin by the lock's spring, which steps on the source's
/// capture clock: it leaves a quarter of the landing offset after 0.1 s and a few percent
/// after 0.2 s, so a plant is judged from 0.2 s of capture time after its landing.
const PLANT_SETTLE_NANOS: u64 = 200_000_000;
/// A message names the frame of the tick the engine saw the change in, checked at the first
/// tick 1/30 s after the last check: a release can reach the message up to two ticks after
/// the lock let go, however late those ticks ran, so the last three frames before a message
/// are not judged (counted in frames: a starved engine's check still waits for a tick).
const PLANT_TAIL_FRAMES: usize = 3;

/// Judges `subject`'s `footplants` messages against its frames (`frames` in arrival order):
/// each foot's position must be FK of the frame the message names (within 0.1 mm, asserted).
/// A planted foot should stand still (the joint it stands on: [`stood_still`]) over its whole
/// plant, from the message that lands it to the one that lifts it (messages about the other
/// feet in between do not restart it); a lifted one travels between one message and the next.
/// Each span is judged after its settle and before its tail ([`PLANT_SETTLE_NANOS`],
/// [`PLANT_TAIL_FRAMES`]), each in the unit it runs on, so a starved server that skips ticks
/// judges the same stretch of motion; a frame sent again with the same `seq` (a tick without a
/// new pose) counts once.
pub fn judge_footplants(
    subject: u32,
    bones: &[rigcast_protocol::control::BoneInfo],
    frames: &[(DecodedFrame, u64)],
    messages: &[ServerMessage],
) -> PlantWatch {
    let mut distinct = std::collections::HashSet::new();
    let frames: Vec<&DecodedFrame> = (frames.iter().map(|(f, _)| f))
        .filter(|f| distinct.insert(f.header.seq))
        .collect();
    let by_seq: std::collections::HashMap<u64, &DecodedFrame> =
        frames.iter().map(|f| (f.header.seq, *f)).collect();
    let index = |name: &str| bones.iter().position(|b| b.name == name).unwrap();
    let plants: Vec<(u64, &Vec<rigcast_protocol::control::FootState>)> = (messages.iter())
        .filter_map(|m| match m {
            ServerMessage::Footplants {
                subject: s,
                seq,
                feet,
            } if *s == subject => Some((*seq, feet)),
            _ => None,
        })
        .collect();
    let mut w = PlantWatch {
        messages: plants.len(),
        checked: 0,
        seen: Default::default(),
        planted_travel: 0.0,
        planted_drift: 0.0,
        planted_judged: 0,
        lifted_travel: 0.0,
    };
    // Each planted foot's landing message (its first message seen planted).
    let mut landed: std::collections::HashMap<&str, u64> = Default::default();
    // Messages whose frame was received (earlier ones came before set_protocol took effect).
    let plants: Vec<_> = (plants.iter())
        .filter(|(seq, _)| by_seq.contains_key(seq))
        .collect();
    for (k, (seq, feet)) in plants.iter().enumerate() {
        let world = wire_fk(bones, by_seq[seq]);
        let next_seq = plants.get(k + 1).map(|n| n.0);
        for foot in feet.iter() {
            w.seen.insert((foot.bone.clone(), foot.planted));
            let error = (world[index(&foot.bone)] - Vec3::from(foot.position)).length();
            assert!(
                error < 1e-4,
                "{}: position off FK of frame {seq} by {error} m",
                foot.bone
            );
            let travel = |from: u64, to: u64| {
                let judged = settled_frames(&frames, by_seq[&from], by_seq[&to]);
                let at = |f: &DecodedFrame| wire_fk(bones, f)[index(&foot.bone)];
                let start = at(judged.first()?);
                let travel = (judged.iter().map(|f| at(f) - start))
                    .map(|p| (p.x * p.x + p.z * p.z).sqrt())
                    .fold(0.0, f32::max);
                (judged.len() >= 3).then_some((travel, judged.len()))
            };
            if foot.planted {
                landed.entry(foot.bone.as_str()).or_insert(*seq);
            } else if let Some(from) = landed.remove(foot.bone.as_str()) {
                let judged = settled_frames(&frames, by_seq[&from], by_seq[seq]);
                if let Some((travel, n)) = stood_still(bones, index(&foot.bone), &judged) {
                    w.planted_travel = w.planted_travel.max(travel);
                    w.planted_drift = w.planted_drift.max(travel / n as f32);
                    w.planted_judged += 1;
                }
            }
            if let Some((travel, _)) = next_seq
                .filter(|_| !foot.planted)
                .and_then(|n| travel(*seq, n))
            {
                w.lifted_travel = w.lifted_travel.max(travel);
            }
        }
        w.checked += 1;
    }
    w
}

/// How far the joint a planted foot stands on moves over the ground along `judged` (the foot
/// bone `foot`'s joint or one of its children's, the lowest on the frame before: a foot
/// rolling over its ball moves its ankle without sliding), and over how many frames; `None`
/// for fewer than three frames.
fn stood_still(
    bones: &[rigcast_protocol::control::BoneInfo],
    foot: usize,
    judged: &[&DecodedFrame],
) -> Option<(f32, usize)> {
    let joints: Vec<usize> = std::iter::once(foot)
        .chain((0..bones.len()).filter(|&b| bones[b].parent == Some(foot as u32)))
        .collect();
    let worlds: Vec<Vec<Vec3>> = judged.iter().map(|f| wire_fk(bones, f)).collect();
    let mut moved = 0.0;
    for w in worlds.windows(2) {
        let lowest = |a: &usize, b: &usize| w[0][*a].y.total_cmp(&w[0][*b].y);
        let contact = joints.iter().copied().min_by(lowest).unwrap_or(foot);
        let d = w[1][contact] - w[0][contact];
        moved += (d.x * d.x + d.z * d.z).sqrt();
    }
    (judged.len() >= 3).then_some((moved, judged.len()))
}

/// The frames from message frame `from` up to message frame `to` that lie past the settle
/// after `from` (capture clock) and before the tail ahead of `to` (ticks).
fn settled_frames<'a>(
    frames: &[&'a DecodedFrame],
    from: &DecodedFrame,
    to: &DecodedFrame,
) -> Vec<&'a DecodedFrame> {
    let settled = from.header.capture_nanos + PLANT_SETTLE_NANOS;
    let mut span: Vec<&DecodedFrame> = (frames.iter().copied())
        .filter(|f| (from.header.seq..to.header.seq).contains(&f.header.seq))
        .collect();
    span.truncate(span.len().saturating_sub(PLANT_TAIL_FRAMES));
    span.retain(|f| f.header.capture_nanos >= settled);
    span
}
