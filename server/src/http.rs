//! The single HTTP listener: WebSocket upgrade on `GET /v1/stream`, JSON status on
//! `GET /v1/status`, and static files (the web viewer) for everything else.
//!
//! ```text
//!  accept ─▶ connection cap (limits.rs: evict the oldest unfinished request, or 503)
//!         ─▶ request head (≤ 16 KiB, ≤ 10 s) ─▶ Host / Origin / token (access.rs: 403, 401)
//!         ─▶ route: upgrade (frames ≤ 64 KiB, checked on the frame header) │ status │ file
//! ```
//!
//! The request head is parsed by hand (method, path, a few headers): the server only needs
//! GET requests, and this keeps an HTTP framework out of the dependency tree. The upgrade uses
//! tungstenite's `derive_accept_key` and hands the socket, plus any bytes read past the head,
//! to `WebSocketStream::from_partially_read`.

use std::borrow::Cow;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio_tungstenite::tungstenite::handshake::derive_accept_key;
use tokio_tungstenite::tungstenite::protocol::{Role, WebSocketConfig};
use tokio_tungstenite::WebSocketStream;

use crate::access::{bearer_token, query_token, AccessPolicy, Credentials, Route};
use crate::batched_writes::BatchedWrites;
use crate::clients::{serve_client, MAX_TRANSPORT_MESSAGE_BYTES};
use crate::limits::Admission;
use crate::model::ServedModel;
use crate::state::ServerState;
use rigcast_protocol::status::{
    ClientAccess, ClientStatus, ClientsStatus, ConnectionsStatus, FootStatus, Status, SubjectStatus,
};

/// Largest request head accepted.
const MAX_HEAD_BYTES: usize = 16 * 1024;
/// A client must finish sending its request head within this time.
const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

/// Accepts connections until shutdown.
pub async fn run_listener(listener: TcpListener, state: Arc<ServerState>) {
    let mut shutdown = state.shutdown.clone();
    loop {
        tokio::select! {
            _ = shutdown.changed() => break,
            accepted = async {
                state.connections.wait_for_room(ROOM_WAIT).await;
                listener.accept().await
            } => {
                match accepted {
                    Ok((stream, peer)) => {
                        // Latency tuning only: the connection works without it.
                        let _ = stream.set_nodelay(true);
                        match state.connections.admit() {
                            Admission::Admitted { permit, evicted } => {
                                tokio::spawn(handle_connection(stream, peer.to_string(), state.clone(), permit, evicted));
                            }
                            Admission::Full => refuse_full(stream, state.connections.max()),
                        }
                    }
                    Err(e) => {
                        // Typically EMFILE; back off briefly rather than spin.
                        tracing::warn!("accept failed: {e}");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                }
            }
        }
    }
}

/// How long a refusal may take to write before the socket is simply closed.
const REFUSAL_TIMEOUT: Duration = Duration::from_secs(1);

/// Longest the listener waits for evicted connections to close before accepting more.
const ROOM_WAIT: Duration = Duration::from_millis(250);

/// Answers a connection the cap has no room for and closes it at once. A new socket's send
/// buffer is empty, so the non-blocking write takes the short answer whole; nothing waits,
/// and the descriptor is released before the next accept.
fn refuse_full(stream: TcpStream, max: usize) {
    let body = format!("server full: {max} connections open; retry later\n");
    // The client may be gone already: there is nobody left to answer.
    let _ = stream.try_write(head(503, "text/plain", body.len()).as_bytes());
    let _ = stream.try_write(body.as_bytes());
}

/// A parsed request head.
#[derive(Debug, Default, PartialEq)]
struct Request {
    method: String,
    path: String,
    upgrade_websocket: bool,
    websocket_key: Option<String>,
    /// `Sec-WebSocket-Version` (only 13 is spoken).
    websocket_version: Option<String>,
    host: Option<String>,
    origin: Option<String>,
    /// From `Authorization: Bearer` or, failing that, `?token=`.
    token: Option<String>,
}

impl Request {
    fn credentials(&self) -> Credentials<'_> {
        Credentials {
            host: self.host.as_deref(),
            origin: self.origin.as_deref(),
            token: self.token.as_deref(),
        }
    }
}

/// Why a request head is refused with 400.
#[derive(Debug, PartialEq)]
enum BadHead {
    /// No method and target on the first line.
    RequestLine,
    /// A header that decides access or the upgrade appears twice (which one counts would be
    /// up to each parser on the way: a proxy could check one and rigcast use the other).
    Repeated(&'static str),
    /// A header line another parser could read differently (RFC 9112 5): folded onto the
    /// previous line, without a colon, with white space before its colon, or holding a bare
    /// CR, LF or NUL (where a proxy might see a second header, rigcast would see one value).
    HeaderLine,
}

impl BadHead {
    fn message(&self) -> String {
        match self {
            BadHead::RequestLine => "bad request: no method and target\n".into(),
            BadHead::Repeated(name) => format!("bad request: more than one {name} header\n"),
            BadHead::HeaderLine => "bad request: a header line that is folded, has no colon, \
                 has white space before its colon or holds a bare CR, LF or NUL\n"
                .into(),
        }
    }
}

/// Sets `slot` once; a second value of the same header is refused.
fn once(slot: &mut Option<String>, value: &str, name: &'static str) -> Result<(), BadHead> {
    if slot.replace(value.to_string()).is_some() {
        return Err(BadHead::Repeated(name));
    }
    Ok(())
}

fn parse_head(head: &str) -> Result<Request, BadHead> {
    let mut lines = head.split("\r\n");
    let first = lines.next().ok_or(BadHead::RequestLine)?;
    // `METHOD SP target SP HTTP/1.x`, nothing else.
    let mut parts = first.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(BadHead::RequestLine);
    };
    if method.is_empty() || target.is_empty() || !version.starts_with("HTTP/1.") {
        return Err(BadHead::RequestLine);
    }
    let method = method.to_string();
    let path = target.split('?').next().unwrap_or(target).to_string();
    let mut req = Request {
        method,
        path,
        token: query_token(target).map(str::to_string),
        ..Request::default()
    };
    let mut authorization = None;
    for line in lines.filter(|l| !l.is_empty()) {
        let Some((name, value)) = line.split_once(':') else {
            return Err(BadHead::HeaderLine);
        };
        let folded_or_spaced = name.is_empty() || name.trim() != name;
        if folded_or_spaced || line.contains(['\r', '\n', '\0']) {
            return Err(BadHead::HeaderLine);
        }
        let value = value.trim();
        match name.trim().to_ascii_lowercase().as_str() {
            "upgrade" => req.upgrade_websocket = value.eq_ignore_ascii_case("websocket"),
            "sec-websocket-key" => once(&mut req.websocket_key, value, "Sec-WebSocket-Key")?,
            "sec-websocket-version" => {
                once(&mut req.websocket_version, value, "Sec-WebSocket-Version")?
            }
            "host" => once(&mut req.host, value, "Host")?,
            "origin" => once(&mut req.origin, value, "Origin")?,
            "authorization" => {
                once(&mut authorization, value, "Authorization")?;
                if let Some(t) = bearer_token(value) {
                    req.token = Some(t.to_string());
                }
            }
            _ => {}
        }
    }
    Ok(req)
}

/// A request head the listener will answer: where it goes and with what access.
#[derive(Debug)]
pub struct RoutedHead {
    /// The route asked for.
    pub route: Route,
    request: Request,
    /// What the request may do there.
    pub access: crate::access::Access,
    /// For [`Route::Model`]: the subject id, or why the path names none.
    model: Option<Result<u32, crate::model::ModelError>>,
}

/// What the listener makes of a complete request head (up to and including its blank line)
/// before any route runs: the route and the access it gets, or the refusal (status, body).
/// No IO, so the head parser and the access rules can be fuzzed without a socket.
pub fn route_head(head: &[u8], policy: &AccessPolicy) -> Result<RoutedHead, (u16, String)> {
    let head = String::from_utf8_lossy(head);
    let request = parse_head(&head).map_err(|bad| (400, bad.message()))?;
    if request.method != "GET" {
        return Err((405, "only GET is supported\n".into()));
    }
    let path = request.path.split(['?', '#']).next().unwrap_or("");
    let model = crate::model::model_request(path);
    let route = match path {
        "/v1/stream" => Route::Stream,
        "/v1/status" => Route::Status,
        _ if model.is_some() => Route::Model,
        _ => Route::ViewerFile,
    };
    let access = policy
        .decide(route, &request.credentials())
        .map_err(|refusal| (refusal.status(), refusal.message()))?;
    Ok(RoutedHead {
        route,
        request,
        access,
        model,
    })
}

async fn handle_connection(
    mut stream: TcpStream,
    peer: String,
    state: Arc<ServerState>,
    permit: crate::limits::ConnectionPermit,
    evicted: tokio::sync::oneshot::Receiver<()>,
) {
    let mut buf = Vec::with_capacity(1024);
    // Each connection is its own task, so a client that never finishes its head (slowloris)
    // holds only this task, and only until the timeout — or until a newer connection needs
    // its slot.
    let mut shutdown = state.shutdown.clone();
    let read = tokio::select! {
        r = tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut stream, &mut buf)) => r,
        // An unfinished request at shutdown is dropped, so the drain does not wait for it.
        _ = async { shutdown.wait_for(|stop| *stop).await.is_ok() } => return,
        Ok(()) = evicted => return refuse_evicted(&mut stream, &state, permit).await,
    };
    permit.promote();
    let head_end = match read {
        Ok(HeadRead::Complete(end)) => end,
        Ok(HeadRead::TooLarge) => {
            // The client may be gone already: there is nobody left to answer.
            let _ = respond(
                &mut stream,
                431,
                "text/plain",
                b"request head larger than 16 KiB\n",
            )
            .await;
            return;
        }
        Ok(HeadRead::Closed) | Err(_) => return,
    };
    let leftover = buf[head_end..].to_vec();
    let RoutedHead {
        route,
        request: req,
        access,
        model,
    } = match route_head(&buf[..head_end], &state.policy) {
        Ok(routed) => routed,
        Err((status, body)) => {
            // The client may be gone already: there is nobody left to answer.
            let _ = respond(&mut stream, status, "text/plain", body.as_bytes()).await;
            return;
        }
    };
    match route {
        Route::Stream => upgrade(stream, req, leftover, state, peer, access, permit).await,
        _ => answer(&mut stream, route, &req.path, model, &state).await,
    }
}

/// Tells a client whose unfinished request made way for a newer connection that the server is
/// full, its slot freed first. The client may be gone already: there is nobody left to answer.
async fn refuse_evicted(
    stream: &mut TcpStream,
    state: &ServerState,
    permit: crate::limits::ConnectionPermit,
) {
    let max = state.connections.max();
    drop(permit);
    let body = format!(
        "server full: {max} connections open; an unfinished request made way for a newer one\n"
    );
    let _ = tokio::time::timeout(
        REFUSAL_TIMEOUT,
        respond(stream, 503, "text/plain", body.as_bytes()),
    )
    .await;
}

/// Answers a request that is not a stream upgrade: the status, a model file or a viewer file.
/// The client may be gone already; then there is nobody left to answer, and no error to keep.
async fn answer(
    stream: &mut TcpStream,
    route: Route,
    path: &str,
    model: Option<Result<u32, crate::model::ModelError>>,
    state: &Arc<ServerState>,
) {
    let _ = match route {
        Route::Status => {
            let body = serde_json::to_vec_pretty(&status(state)).unwrap_or_default();
            respond(stream, 200, "application/json", &body).await
        }
        // `Route::Model` is chosen only when the path is a model request.
        Route::Model => match model {
            Some(Ok(id)) => serve_model(stream, state, id).await,
            Some(Err(e)) => respond(stream, 404, "text/plain", format!("{e}\n").as_bytes()).await,
            None => respond(stream, 404, "text/plain", b"no subject\n").await,
        },
        // `Route::Stream` is upgraded before an answer is asked for.
        Route::ViewerFile | Route::Stream => match static_asset(path) {
            Some((mime, body)) => respond(stream, 200, mime, &body).await,
            None => respond(stream, 404, "text/plain", b"not found\n").await,
        },
    };
}

/// The answer to `GET /v1/subjects/{id}/model.glb`: the target's configured model file,
/// streamed from disk in [`crate::model::MODEL_CHUNK_BYTES`] pieces (a client that does not
/// read holds one piece, not the file), or a 404 saying why there is none.
async fn serve_model(
    stream: &mut TcpStream,
    state: &Arc<ServerState>,
    id: u32,
) -> std::io::Result<()> {
    let not_found = |message: String| format!("{message}\n").into_bytes();
    let Some(subject) = state.subject(id) else {
        return respond(
            stream,
            404,
            "text/plain",
            &not_found(format!("no subject {id}")),
        )
        .await;
    };
    let Some(model) = subject.model.clone() else {
        let why = format!(
            "subject {id} ({}) has no model file (only .glb/.vrm targets have one)",
            subject.info().name
        );
        return respond(stream, 404, "text/plain", &not_found(why)).await;
    };
    let (file, len) = match model.open().await {
        Ok(opened) => opened,
        Err(e) => return respond(stream, 404, "text/plain", &not_found(e.to_string())).await,
    };
    let write = async {
        use tokio::io::AsyncReadExt;
        stream
            .write_all(head(200, "model/gltf-binary", len as usize).as_bytes())
            .await?;
        let mut chunks =
            tokio::io::BufReader::with_capacity(crate::model::MODEL_CHUNK_BYTES, file.take(len));
        tokio::io::copy_buf(&mut chunks, stream).await?;
        stream.shutdown().await
    };
    tokio::time::timeout(MODEL_TIMEOUT, write)
        .await
        .unwrap_or_else(|_| Err(std::io::ErrorKind::TimedOut.into()))
}

/// Longest a model download may take (a client that stops reading is dropped then).
const MODEL_TIMEOUT: Duration = Duration::from_secs(60);

/// `GET /v1/stream`: answers the WebSocket upgrade and runs the client session; the
/// connection's slot (`permit`) is held until the session ends.
async fn upgrade(
    mut stream: TcpStream,
    req: Request,
    leftover: Vec<u8>,
    state: Arc<ServerState>,
    peer: String,
    access: crate::access::Access,
    permit: crate::limits::ConnectionPermit,
) {
    let (true, Some(key)) = (req.upgrade_websocket, req.websocket_key) else {
        // The client may be gone already: there is nobody left to answer.
        let _ = respond(
            &mut stream,
            426,
            "text/plain",
            b"this endpoint needs a WebSocket upgrade\n",
        )
        .await;
        return;
    };
    if req.websocket_version.as_deref() != Some("13") {
        // RFC 6455 4.2.2: refuse, naming the version spoken.
        let body = b"this server speaks WebSocket version 13 only\n";
        let response = format!(
            "HTTP/1.1 426 Upgrade Required\r\nSec-WebSocket-Version: 13\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            body.len()
        );
        // The client may be gone already: there is nobody left to answer.
        let _ = stream
            .write_all(&[response.as_bytes(), body].concat())
            .await;
        return;
    }
    let accept = derive_accept_key(key.as_bytes());
    let Ok(mut stream) = limit_send_buffer(stream, CLIENT_SEND_BUFFER_BYTES) else {
        return;
    };
    // Frames are written whole, one write per tick: Nagle's algorithm would only hold the
    // next tick's write back waiting for an ACK. Safe to drop the error: a socket where the
    // option cannot be set still streams, only with that delay.
    let _ = stream.set_nodelay(true);
    let response = format!(
            "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
        );
    if stream.write_all(response.as_bytes()).await.is_err() {
        return;
    }
    let ws = WebSocketStream::from_partially_read(
        BatchedWrites::new(stream, CLIENT_WRITE_BATCH_BYTES),
        leftover,
        Role::Server,
        Some(websocket_config()),
    )
    .await;
    let client_id = state.next_client_id.fetch_add(1, Ordering::Relaxed);
    // The session sees its part of the state only.
    serve_client(ws, state.sessions(), client_id, peer, access).await;
    drop(permit);
}

/// Read buffer per WebSocket client: client messages are small JSON, and many idle clients
/// should cost little (tungstenite allocates this eagerly; its default is 128 KiB).
const CLIENT_READ_BUFFER_BYTES: usize = 4 * 1024;

/// Bytes of a client's writes held until its session flushes (see [`BatchedWrites`]): a
/// tick's frames (two 65-bone characters' v2 frames are ~2.2 kB) go out in one write.
const CLIENT_WRITE_BATCH_BYTES: usize = 4 * 1024;

/// Limits for client connections. The frame limit is checked on the frame header, so a
/// client announcing a 16 MB frame is refused before a byte of it is buffered; frames are
/// passed to the socket as they are sent (no write buffering in tungstenite: its buffer grows
/// with a lagging batch; [`BatchedWrites`] holds a tick's frames instead).
pub fn websocket_config() -> WebSocketConfig {
    WebSocketConfig::default()
        .read_buffer_size(CLIENT_READ_BUFFER_BYTES)
        .write_buffer_size(0)
        .max_message_size(Some(MAX_TRANSPORT_MESSAGE_BYTES))
        .max_frame_size(Some(MAX_TRANSPORT_MESSAGE_BYTES))
}

/// Kernel send buffer per WebSocket client. Small on purpose: frames are realtime, and a large
/// buffer (Linux autotunes up to megabytes) would hold seconds of stale frames for a slow
/// client before the broadcast channel notices it lagging. 64 KiB is ~1 s of a 65-bone stream
/// at 60 Hz.
pub const CLIENT_SEND_BUFFER_BYTES: u32 = 64 * 1024;

/// Sets SO_SNDBUF. tokio exposes the option only on `TcpSocket`, so the option is set through a
/// duplicate descriptor of the same socket (the option belongs to the socket, not the fd).
fn limit_send_buffer(stream: TcpStream, bytes: u32) -> std::io::Result<TcpStream> {
    let std_stream = stream.into_std()?;
    let dup = tokio::net::TcpSocket::from_std_stream(std_stream.try_clone()?);
    dup.set_send_buffer_size(bytes)?;
    drop(dup);
    TcpStream::from_std(std_stream)
}

/// How reading a request head ended.
enum HeadRead {
    /// The head ends at this offset (after `\r\n\r\n`); later bytes are already in the buffer.
    Complete(usize),
    /// More than [`MAX_HEAD_BYTES`] without the blank line.
    TooLarge,
    /// The peer closed the connection or the read failed.
    Closed,
}

/// Reads until the blank line ending the head.
async fn read_head(stream: &mut TcpStream, buf: &mut Vec<u8>) -> HeadRead {
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(pos) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            return HeadRead::Complete(pos + 4);
        }
        if buf.len() > MAX_HEAD_BYTES {
            return HeadRead::TooLarge;
        }
        match stream.read(&mut chunk).await {
            Ok(0) | Err(_) => return HeadRead::Closed,
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
        }
    }
}

/// A client must take a whole response within this time: a connection that requests the
/// viewer's largest file and never reads must not hold its slot under the cap forever.
const RESPONSE_TIMEOUT: Duration = Duration::from_secs(10);

async fn respond(
    stream: &mut TcpStream,
    status: u16,
    mime: &str,
    body: &[u8],
) -> std::io::Result<()> {
    let write = async {
        stream
            .write_all(head(status, mime, body.len()).as_bytes())
            .await?;
        stream.write_all(body).await?;
        stream.shutdown().await
    };
    tokio::time::timeout(RESPONSE_TIMEOUT, write)
        .await
        .unwrap_or_else(|_| Err(std::io::ErrorKind::TimedOut.into()))
}

/// A response head (every response closes the connection).
fn head(status: u16, mime: &str, body_len: usize) -> String {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        503 => "Service Unavailable",
        404 => "Not Found",
        405 => "Method Not Allowed",
        426 => "Upgrade Required",
        431 => "Request Header Fields Too Large",
        _ => "Error",
    };
    let retry = if status == 503 {
        "Retry-After: 1\r\n"
    } else {
        ""
    };
    format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {mime}\r\nContent-Length: {body_len}\r\nCache-Control: no-cache\r\n{retry}Connection: close\r\n\r\n"
    )
}

/// The web viewer's files (`clients/web/`), embedded at build time so `rigcast serve` needs
/// neither the source tree nor a CDN. `"/"` is the index page. Query strings are ignored.
pub fn static_asset(path: &str) -> Option<(&'static str, Cow<'static, [u8]>)> {
    let path = path.split(['?', '#']).next().unwrap_or(path);
    let path = if path == "/" { "/index.html" } else { path };
    VIEWER_FILES
        .iter()
        .find(|(p, _, _)| *p == path)
        .map(|(_, mime, bytes)| (*mime, Cow::Borrowed(*bytes)))
}

macro_rules! viewer_file {
    ($path:literal, $mime:literal) => {
        (
            $path,
            $mime,
            include_bytes!(concat!("../../clients/web", $path)) as &[u8],
        )
    };
}

/// Every file the viewer loads; keep in step with `clients/web/` (the viewer test loads them all).
const VIEWER_FILES: &[(&str, &str, &[u8])] = &[
    viewer_file!("/index.html", "text/html; charset=utf-8"),
    viewer_file!("/style.css", "text/css; charset=utf-8"),
    viewer_file!("/app.js", "text/javascript; charset=utf-8"),
    viewer_file!("/stream.js", "text/javascript; charset=utf-8"),
    viewer_file!("/graph.js", "text/javascript; charset=utf-8"),
    viewer_file!(
        "/vendor/three/three.module.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!(
        "/vendor/three/three.core.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!("/vendor/three/LICENSE", "text/plain; charset=utf-8"),
    viewer_file!(
        "/vendor/three/addons/loaders/GLTFLoader.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!(
        "/vendor/three/addons/utils/BufferGeometryUtils.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!(
        "/vendor/three/addons/utils/SkeletonUtils.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!(
        "/vendor/three/addons/controls/OrbitControls.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!(
        "/vendor/three-vrm/three-vrm.module.min.js",
        "text/javascript; charset=utf-8"
    ),
    viewer_file!("/vendor/three-vrm/LICENSE", "text/plain; charset=utf-8"),
    viewer_file!("/model.js", "text/javascript; charset=utf-8"),
    viewer_file!("/controls.js", "text/javascript; charset=utf-8"),
    viewer_file!("/budget.js", "text/javascript; charset=utf-8"),
    viewer_file!("/decimate.js", "text/javascript; charset=utf-8"),
];

/// The foot-lock part of a subject's status.
fn footplants(stats: &rigcast_engine::stats::SubjectStats) -> Option<Vec<FootStatus>> {
    let names = stats.locked_feet.lock().ok()?;
    if names.is_empty() {
        return None;
    }
    let bits = stats.feet_locked.load(Ordering::Relaxed);
    Some(
        names
            .iter()
            .enumerate()
            .map(|(i, bone)| FootStatus {
                bone: bone.clone(),
                planted: i < 32 && bits & (1 << i) != 0,
            })
            .collect(),
    )
}

/// Snapshot of the counters.
pub fn status(state: &ServerState) -> Status {
    let now = std::time::Instant::now();
    let subjects = (state.subjects().iter())
        .map(|s| subject_status(s, now))
        .collect();
    let list = client_list(state);
    Status {
        server_version: env!("CARGO_PKG_VERSION").to_string(),
        tick_hz: state.rate_hz,
        output_rate_hz: state.stats.output.rate_hz(now),
        subjects,
        clients: ClientsStatus {
            count: list.len(),
            list,
        },
        dropped_frames_total: state.stats.dropped_frames.load(Ordering::Relaxed),
        vmc_send_errors: state.stats.vmc_send_errors.load(Ordering::Relaxed),
        tick_micros: state.stats.tick_percentiles(),
        connections: ConnectionsStatus {
            open: state.connections.open(),
            max: state.connections.max(),
            refused_total: state.connections.refused(),
            evicted_total: state.connections.evicted(),
            fd_limit: state.fd_limit.map(|l| l.soft),
        },
        control_resyncs_total: state.stats.control_resyncs.load(Ordering::Relaxed),
        stalled_disconnects_total: state.stats.stalled_disconnects.load(Ordering::Relaxed),
        recording: state.recorder.as_ref().map(|r| r.status()),
        cluster: cluster_status(state),
    }
}

/// One subject's line in the status: its input, health, faults, footplants and latency.
fn subject_status(s: &rigcast_engine::subject::Subject, now: std::time::Instant) -> SubjectStatus {
    let info = s.info();
    SubjectStatus {
        id: info.id,
        name: info.name,
        num_bones: info.num_bones,
        input_fps: s.stats.input.rate_hz(now),
        input_frames: s.stats.input.total(),
        last_capture_nanos: s.stats.last_capture_nanos.load(Ordering::Relaxed),
        kind: s.info().kind,
        inputs: s.inputs.clone(),
        source: s.source_health(now),
        listen: s.listen_addr.map(|a| a.to_string()),
        skeleton_changes: s.stats.skeleton_changes.load(Ordering::Relaxed),
        skeleton_frames_limited: s.stats.skeleton_frames_limited.load(Ordering::Relaxed),
        rejected_poses: s.stats.rejected_poses.load(Ordering::Relaxed),
        last_rejection: s.stats.last_rejection.lock().ok().and_then(|r| r.clone()),
        fault: s.stats.fault(),
        faults_total: s.stats.faults_total.load(Ordering::Relaxed),
        footplants: footplants(&s.stats),
        latency: s.stats.wire.lock().map(|w| w.report()).unwrap_or_default(),
    }
}

/// The connected clients, by id.
fn client_list(state: &ServerState) -> Vec<ClientStatus> {
    let Ok(clients) = state.stats.clients.lock() else {
        return Vec::new();
    };
    clients
        .iter()
        .map(|(id, c)| ClientStatus {
            id: *id,
            peer: c.peer.clone(),
            frames_sent: c.frames_sent.load(Ordering::Relaxed),
            missed_frames: c.missed_frames.load(Ordering::Relaxed),
            access: match c.access {
                crate::access::Access::ReadOnly => ClientAccess::ReadOnly,
                crate::access::Access::Control => ClientAccess::Control,
            },
            control_resyncs: c.control_resyncs.load(Ordering::Relaxed),
        })
        .collect()
}

fn cluster_status(state: &ServerState) -> Option<rigcast_protocol::status::ClusterStatus> {
    let cluster = state.cluster.as_ref()?;
    let site = cluster.site.clone();
    let (s, m) = (&state.stats, &cluster.mapping_counts);
    let n = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    Some(rigcast_protocol::status::ClusterStatus {
        site,
        publish_errors: n(&s.cluster_publish_errors),
        bad_frames: n(&s.cluster_bad_frames),
        control_forwarded: n(&s.cluster_control_forwarded),
        control_served: n(&s.cluster_control_served),
        control_refused: n(&s.cluster_control_refused),
        subjects_discovered: n(&s.cluster_subjects_discovered),
        mappings_from_cluster: n(&m.fetched),
        mappings_shared: n(&m.shared),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_upgrade_request() {
        let head = "GET /v1/stream?x=1 HTTP/1.1\r\nHost: a\r\nUpgrade: WebSocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n";
        let r = parse_head(head).unwrap();
        assert_eq!(r.method, "GET");
        assert_eq!(r.path, "/v1/stream");
        assert!(r.upgrade_websocket);
        assert_eq!(r.websocket_key.as_deref(), Some("dGhlIHNhbXBsZSBub25jZQ=="));
        // RFC 6455 §1.3 worked example.
        assert_eq!(
            derive_accept_key(b"dGhlIHNhbXBsZSBub25jZQ=="),
            "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="
        );
        assert!(parse_head("").is_err());
        // A request line without a target, and a bare blank line.
        assert!(parse_head("GET\r\n\r\n").is_err());
        assert!(parse_head("\r\n\r\n").is_err());
        // HTTP/1.0 and no Host are fine.
        let r = parse_head("GET /v1/status HTTP/1.0\r\nAccept: */*\r\n\r\n").unwrap();
        assert_eq!((r.method.as_str(), r.path.as_str()), ("GET", "/v1/status"));
        assert!(!r.upgrade_websocket && r.websocket_key.is_none());
    }

    #[test]
    fn header_lines_other_parsers_could_read_differently_are_refused() {
        for line in [
            "garbage",
            " Host: evil.example",
            "\tX-Folded: on",
            "Host : evil.example",
            ": empty name",
            "X: a\nHost: evil.example",
            "X: a\rHost: evil.example",
            "X: a\0b",
        ] {
            let head = format!("GET /v1/status HTTP/1.1\r\nHost: localhost\r\n{line}\r\n\r\n");
            assert_eq!(parse_head(&head), Err(BadHead::HeaderLine), "{line:?}");
        }
        for first in [
            "GET /v1/status",
            "GET  /v1/status HTTP/1.1",
            "GET /v1/status HTTP/2",
            "GET /a b HTTP/1.1",
        ] {
            let head = format!("{first}\r\nHost: localhost\r\n\r\n");
            assert_eq!(parse_head(&head), Err(BadHead::RequestLine), "{first:?}");
        }
    }

    #[test]
    fn repeated_deciding_headers_are_refused() {
        for name in [
            "Host",
            "Origin",
            "Authorization",
            "Sec-WebSocket-Key",
            "Sec-WebSocket-Version",
        ] {
            let head = format!(
                "GET / HTTP/1.1\r\n{name}: a\r\n{}: b\r\n\r\n",
                name.to_lowercase()
            );
            assert_eq!(parse_head(&head), Err(BadHead::Repeated(name)), "{name}");
        }
        // Other headers may repeat.
        assert!(parse_head("GET / HTTP/1.1\r\nAccept: a\r\nAccept: b\r\n\r\n").is_ok());
    }

    #[test]
    fn static_hook_serves_placeholder() {
        assert!(static_asset("/").is_some());
        assert!(static_asset("/nope.js").is_none());
        // Embedded files only: traversal finds nothing.
        assert!(static_asset("/../../etc/passwd").is_none());
        assert!(static_asset("/vendor/../index.html").is_none());
    }
}
