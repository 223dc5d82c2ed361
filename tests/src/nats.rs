//! Real NATS for the cluster tests: Debian's `nats-server` with JetStream, as one server or a
//! cluster of three on loopback ports, and `rigcast serve` nodes joined to it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rigcast_protocol::control::SubjectInfo;
use rigcast_protocol::{ServerMessage, SourceState};

use crate::{
    connect, free_port, handshake, next, next_json, temp_path, Incoming, ServeProcess, Ws,
};

/// The `nats-server` binary, or `None` (with a printed reason) when it is absent and
/// `RIGCAST_SKIP_APPS=1`; absent otherwise is a failure. Debian installs it in /usr/sbin,
/// which is not always on PATH.
pub fn nats_server() -> Option<PathBuf> {
    let on_path = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join("nats-server"))
            .find(|p| p.is_file())
    });
    let found = on_path.or_else(|| {
        let p = PathBuf::from("/usr/sbin/nats-server");
        p.is_file().then_some(p)
    });
    if found.is_none() {
        if std::env::var("RIGCAST_SKIP_APPS").as_deref() == Ok("1") {
            eprintln!("SKIP: nats-server not installed and RIGCAST_SKIP_APPS=1");
            return None;
        }
        panic!("nats-server not found: run scripts/install-apps.sh (or set RIGCAST_SKIP_APPS=1)");
    }
    found
}

/// NATS servers with JetStream (clustered when more than one), killed on drop.
pub struct NatsCluster {
    servers: Vec<Option<Child>>,
    client_ports: Vec<u16>,
}

impl NatsCluster {
    /// Three clustered servers.
    pub fn start(bin: &Path) -> NatsCluster {
        Self::start_n(bin, 3)
    }

    /// `n` servers (one: no cluster), healthy (JetStream ready) when this returns.
    ///
    /// Ports are chosen free and then handed to the servers, so another process (any test's
    /// outgoing connection takes a port from the same range) can take one in between; that
    /// server then exits at once. Such a start is thrown away and tried again on fresh ports,
    /// three times at most; a cluster that stays up and unhealthy for 30 s fails as before.
    pub fn start_n(bin: &Path, n: usize) -> NatsCluster {
        let mut last = String::new();
        for attempt in 1..=3 {
            match Self::try_start(bin, n) {
                Ok(cluster) => return cluster,
                Err(why) => {
                    eprintln!("NATS start {attempt} of 3 failed: {why}");
                    last = why;
                }
            }
        }
        panic!("NATS cluster did not start: {last}");
    }

    fn try_start(bin: &Path, n: usize) -> Result<NatsCluster, String> {
        let client_ports: Vec<u16> = (0..n).map(|_| free_port()).collect();
        let route_ports: Vec<u16> = (0..n).map(|_| free_port()).collect();
        let monitor_ports: Vec<u16> = (0..n).map(|_| free_port()).collect();
        let routes = route_ports
            .iter()
            .map(|p| format!("nats://127.0.0.1:{p}"))
            .collect::<Vec<_>>()
            .join(",");
        let dir = temp_path("nats-cluster");
        let servers = (0..n)
            .map(|i| {
                let store = dir.join(format!("n{i}"));
                std::fs::create_dir_all(&store).unwrap();
                let mut cmd = Command::new(bin);
                cmd.args(["-a", "127.0.0.1", "-p", &client_ports[i].to_string()])
                    .args(["-m", &monitor_ports[i].to_string()])
                    .args(["-n", &format!("n{i}")]);
                if n > 1 {
                    cmd.args(["--cluster_name", "rigcast-test"])
                        .args(["--cluster", &format!("nats://127.0.0.1:{}", route_ports[i])])
                        .args(["--routes", &routes]);
                }
                let child = cmd
                    .args(["-js", "-sd"])
                    .arg(&store)
                    .stdout(Stdio::null())
                    .stderr(Stdio::null())
                    .spawn()
                    .expect("nats-server starts");
                Some(child)
            })
            .collect();
        // Dropped on an early return: the servers started are killed.
        let mut cluster = NatsCluster {
            servers,
            client_ports,
        };
        // JetStream needs its meta leader elected before a KV bucket can be made.
        let deadline = Instant::now() + Duration::from_secs(30);
        for port in &monitor_ports {
            while !healthy(*port) {
                if let Some(i) = cluster.exited() {
                    return Err(format!("server {i} exited (a port taken before it bound?)"));
                }
                assert!(
                    Instant::now() < deadline,
                    "NATS cluster not healthy in 30 s"
                );
                std::thread::sleep(Duration::from_millis(200));
            }
        }
        Ok(cluster)
    }

    /// The first server that has exited, if any.
    fn exited(&mut self) -> Option<usize> {
        self.servers.iter_mut().position(|s| {
            s.as_mut()
                .is_some_and(|c| c.try_wait().ok().flatten().is_some())
        })
    }

    /// The servers' URLs, comma-separated (as `--nats` takes them).
    pub fn urls(&self) -> String {
        self.client_ports
            .iter()
            .map(|p| format!("nats://127.0.0.1:{p}"))
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Kills server `i`.
    pub fn kill(&mut self, i: usize) {
        if let Some(mut c) = self.servers[i].take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Drop for NatsCluster {
    fn drop(&mut self) {
        for i in 0..self.servers.len() {
            self.kill(i);
        }
    }
}

/// NATS's own health check, JetStream included.
fn healthy(monitor_port: u16) -> bool {
    use std::io::{Read, Write};
    let Ok(mut s) = std::net::TcpStream::connect(("127.0.0.1", monitor_port)) else {
        return false;
    };
    let _ = s.set_read_timeout(Some(Duration::from_secs(2)));
    let req = "GET /healthz HTTP/1.0\r\nHost: localhost\r\n\r\n";
    if s.write_all(req.as_bytes()).is_err() {
        return false;
    }
    let mut body = String::new();
    let _ = s.read_to_string(&mut body);
    body.contains("\"ok\"")
}

/// `rigcast serve ARGS` with its own config folder; with `token`, that folder's token file
/// holds it (nodes of one deployment share their token).
pub fn node_with_token(args: &[String], name: &str, token: Option<&str>) -> ServeProcess {
    let home = temp_path(&format!("xdg-cluster-{name}"));
    std::fs::create_dir_all(&home).unwrap();
    if let Some(t) = token {
        let dir = home.join("rigcast");
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("token");
        std::fs::write(&file, t).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    ServeProcess::start(&args, home, None)
}

/// [`node_with_token`] off the async runtime, with a token of its own.
pub async fn spawn_node(args: Vec<String>, name: &'static str) -> ServeProcess {
    spawn_node_with_token(args, name, None).await
}

/// [`node_with_token`] off the async runtime.
pub async fn spawn_node_with_token(
    args: Vec<String>,
    name: &'static str,
    token: Option<&'static str>,
) -> ServeProcess {
    tokio::task::spawn_blocking(move || node_with_token(&args, name, token))
        .await
        .unwrap()
}

/// A client (with `?token=` when given) and the subjects its server announced, by name.
pub async fn client_with(
    p: &ServeProcess,
    token: Option<&str>,
) -> (Ws, HashMap<String, SubjectInfo>) {
    let query = token.map(|t| format!("?token={t}")).unwrap_or_default();
    let mut ws = connect(&format!("ws://{}/v1/stream{query}", p.addr)).await;
    let (hello, _) = handshake(&mut ws).await;
    let ServerMessage::Hello { subjects, .. } = hello else {
        panic!("no hello: {hello:?}");
    };
    (
        ws,
        subjects.into_iter().map(|s| (s.name.clone(), s)).collect(),
    )
}

/// A client without the token.
pub async fn client(p: &ServeProcess) -> (Ws, HashMap<String, SubjectInfo>) {
    client_with(p, None).await
}

/// Waits until a `source_status` shows subject `id` in `state` with a detail containing
/// `detail_has` (`""`: any); that detail and how long it took.
pub async fn wait_state(
    ws: &mut Ws,
    id: u32,
    state: SourceState,
    detail_has: &str,
    timeout: Duration,
) -> Option<(String, Duration)> {
    let start = Instant::now();
    let end = start + timeout;
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        if let ServerMessage::SourceStatus { sources, .. } = next_json(ws, left).await? {
            let hit = sources
                .iter()
                .find(|s| s.subject == id && s.state == state && s.detail.contains(detail_has));
            if let Some(s) = hit {
                return Some((s.detail.clone(), start.elapsed()));
            }
        }
    }
    None
}

/// Waits for a `subjects_changed` naming `name`; its id.
pub async fn wait_subject(ws: &mut Ws, name: &str, timeout: Duration) -> Option<u32> {
    let end = Instant::now() + timeout;
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        if let ServerMessage::SubjectsChanged { subjects } = next_json(ws, left).await? {
            if let Some(s) = subjects.iter().find(|s| s.name == name) {
                return Some(s.id);
            }
        }
    }
    None
}

/// (seq, rotations) of every frame of subject `id` received for `secs`.
pub async fn frames_of(ws: &mut Ws, id: u32, secs: f64) -> Vec<(u64, Vec<glam::Quat>)> {
    let mut out = Vec::new();
    let end = Instant::now() + Duration::from_secs_f64(secs);
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match next(ws, left).await {
            Some(Incoming::Frame(f, _)) if f.header.subject == id => {
                out.push((f.header.seq, f.rotations))
            }
            Some(_) => {}
            None => break,
        }
    }
    out
}

/// Writes `body` as `rigcast.toml` in a fresh folder named after `name`; its path.
pub fn config_file(name: &str, body: &str) -> PathBuf {
    let dir = temp_path(&format!("cluster-config-{name}"));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("rigcast.toml");
    std::fs::write(&path, body).unwrap();
    path
}

/// One `nats-server` (JetStream on) started off the async runtime; `None` when the binary is
/// absent and may be (see [`nats_server`]).
pub async fn one_nats_server() -> Option<NatsCluster> {
    let bin = nats_server()?;
    Some(
        tokio::task::spawn_blocking(move || NatsCluster::start_n(&bin, 1))
            .await
            .unwrap(),
    )
}

/// Compares a relayed subject's frames with the originating node's by seq: the number of
/// frames matched, after asserting equal rotations and non-decreasing seqs.
pub fn frames_equal(
    origin: &[(u64, Vec<glam::Quat>)],
    relayed: &[(u64, Vec<glam::Quat>)],
    what: &str,
) -> usize {
    assert!(
        relayed.windows(2).all(|w| w[0].0 <= w[1].0),
        "{what}: frames out of order"
    );
    let by_seq: HashMap<u64, &Vec<glam::Quat>> = origin.iter().map(|(s, r)| (*s, r)).collect();
    let mut matched = 0;
    for (seq, rot) in relayed {
        let Some(o) = by_seq.get(seq) else { continue };
        assert_eq!(o.len(), rot.len(), "{what}: bone count");
        for (a, b) in o.iter().zip(rot) {
            let d = (glam::Vec4::from(*a) - glam::Vec4::from(*b))
                .abs()
                .max_element();
            assert!(d <= 1e-6, "{what}: seq {seq} differs by {d}");
        }
        matched += 1;
    }
    matched
}
