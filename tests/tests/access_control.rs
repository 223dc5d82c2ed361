//! Who may use the server: a web page from another origin (or `null`), a request naming a
//! foreign Host (DNS rebinding) and a client without the control token are refused through
//! the real listener; with the token, changes work. A listener beyond loopback needs the
//! token for streaming too. An oversized frame is refused on its header.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use rigcast_protocol::control::ErrorCode;
use rigcast_protocol::ServerMessage;
use rigcast_server::ServerConfig;
use rigcast_tests::*;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const WAIT: Duration = Duration::from_secs(5);

/// A WebSocket upgrade request for `path` with extra header lines.
fn upgrade(path: &str, headers: &[(&str, &str)]) -> String {
    let mut r = format!(
        "GET {path} HTTP/1.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
    );
    for (k, v) in headers {
        r.push_str(&format!("{k}: {v}\r\n"));
    }
    r + "\r\n"
}

/// A plain GET with extra header lines.
fn get(path: &str, headers: &[(&str, &str)]) -> String {
    let mut r = format!("GET {path} HTTP/1.1\r\nConnection: close\r\n");
    for (k, v) in headers {
        r.push_str(&format!("{k}: {v}\r\n"));
    }
    r + "\r\n"
}

/// Sends `raw` and returns the status code of the answer's head (the connection may stay
/// open after a 101, so only the head is read), and the socket.
async fn exchange(addr: SocketAddr, raw: &str) -> (u16, String, TcpStream) {
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(raw.as_bytes()).await.unwrap();
    let mut head = Vec::new();
    tokio::time::timeout(WAIT, async {
        while !head.ends_with(b"\r\n\r\n") {
            match s.read_u8().await {
                Ok(b) => head.push(b),
                Err(_) => break,
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("no answer to {raw:?}"));
    let text = String::from_utf8_lossy(&head).into_owned();
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {text:?} for {raw:?}"));
    (code, text, s)
}

async fn status_code(addr: SocketAddr, raw: &str) -> u16 {
    exchange(addr, raw).await.0
}

/// Every file in the mapping cache folder with its content.
fn cache_contents(dir: &Path) -> BTreeMap<String, String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read_to_string(&p).unwrap(),
            )
        })
        .collect()
}

/// The mapping a fresh client is greeted with for subject 1.
async fn current_mapping(url: &str) -> ServerMessage {
    let mut ws = connect(url).await;
    loop {
        match next_json(&mut ws, WAIT).await.expect("greeting") {
            m @ ServerMessage::Mapping { subject: 1, .. } => return m,
            _ => continue,
        }
    }
}

async fn expect_error(ws: &mut Ws, want: ErrorCode) -> String {
    loop {
        match next_json(ws, WAIT).await {
            Some(ServerMessage::Error { code, message, .. }) => {
                assert_eq!(code, want, "{message}");
                return message;
            }
            Some(ServerMessage::Ack { .. }) => panic!("expected {want:?}, got an ack"),
            Some(_) => continue,
            None => panic!("no {want:?} error"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn foreign_origins_hosts_and_tokenless_changes_are_refused() {
    let cache_dir = temp_path("cache").with_file_name("mappings");
    // The default demo: the walk (subject 0) and the mannequin retargeted from it (1).
    let server = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        mapping_cache_dir: Some(cache_dir.clone()),
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let addr = server.local_addr();
    let host = addr.to_string();
    let own_origin = format!("http://{host}");

    // The served viewer's own origin and non-browser clients (no Origin) are let in.
    let allowed: [&[(&str, &str)]; 3] = [
        &[("Host", &host), ("Origin", &own_origin)],
        &[("Host", &host)],
        &[("Host", &format!("localhost:{}", addr.port()))],
    ];
    for headers in allowed {
        assert_eq!(
            status_code(addr, &upgrade("/v1/stream", headers)).await,
            101,
            "{headers:?}"
        );
    }
    // A page elsewhere (another port is another origin), a sandboxed or file page (`null`),
    // and a rebinding attacker's name are refused, on every route.
    let other_port = format!("http://127.0.0.1:{}", addr.port() + 1);
    let refused: [&[(&str, &str)]; 5] = [
        &[("Host", &host), ("Origin", "http://evil.example")],
        &[("Host", &host), ("Origin", "null")],
        &[("Host", &host), ("Origin", &other_port)],
        &[
            ("Host", "evil.example:8717"),
            ("Origin", "http://evil.example:8717"),
        ],
        &[("Host", "evil.example")],
    ];
    for headers in refused {
        for raw in [
            upgrade("/v1/stream", headers),
            get("/v1/status", headers),
            get("/", headers),
        ] {
            let (code, head, _) = exchange(addr, &raw).await;
            assert_eq!(code, 403, "{raw:?} → {head}");
        }
    }
    let (head, _) = http_get(addr, "/v1/status").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    // A wrong token is refused outright rather than quietly downgraded.
    let wrong = "f".repeat(64);
    assert_eq!(
        status_code(addr, &upgrade(&format!("/v1/stream?token={wrong}"), &[])).await,
        401
    );
    assert_eq!(
        status_code(
            addr,
            &upgrade(
                "/v1/stream",
                &[("Authorization", &format!("Bearer {wrong}"))]
            )
        )
        .await,
        401
    );

    // A read-only client may stream but not change anything.
    let before_mapping = current_mapping(&server.stream_url()).await;
    let before_cache = cache_contents(&cache_dir);
    assert_eq!(before_cache.len(), 1, "the demo's mapping is cached");
    let mut viewer = connect(&server.stream_url()).await;
    handshake(&mut viewer).await;
    let frames = collect_frames(&mut viewer, Duration::from_millis(300)).await;
    assert!(!frames.is_empty(), "read-only streaming works");
    send_text(
        &mut viewer,
        r#"{"type":"set_mapping","subject":1,"overrides":{"thigh_l":null}}"#,
    )
    .await;
    let message = expect_error(&mut viewer, ErrorCode::Unauthorized).await;
    assert!(
        message.contains("set_mapping") && message.contains("token"),
        "{message}"
    );
    send_text(&mut viewer, r#"{"type":"calibrate","subject":0}"#).await;
    expect_error(&mut viewer, ErrorCode::Unauthorized).await;
    // Nothing changed: no mapping was broadcast, the cache on disk is as it was.
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(current_mapping(&server.stream_url()).await, before_mapping);
    assert_eq!(cache_contents(&cache_dir), before_cache);

    // With the token (here as an Authorization header, as the Blender add-on sends it) the
    // same request works: acked, broadcast, cached.
    let request = rigcast_server::token::authorized_request(
        &server.stream_url(),
        Some(server.control_token()),
    )
    .unwrap();
    let (mut control, _) = tokio_tungstenite::connect_async(request).await.unwrap();
    handshake(&mut control).await;
    send_text(
        &mut control,
        r#"{"type":"set_mapping","subject":1,"overrides":{"thigh_l":null}}"#,
    )
    .await;
    let mut acked = false;
    let entries = loop {
        match next_json(&mut control, WAIT)
            .await
            .expect("ack and mapping")
        {
            ServerMessage::Ack { subject: 1, .. } => acked = true,
            ServerMessage::Error { code, message, .. } => panic!("{code:?}: {message}"),
            ServerMessage::Mapping { entries, .. } if acked => break entries,
            _ => {}
        }
    };
    let thigh = entries.iter().find(|e| e.target == "thigh_l").unwrap();
    assert_eq!(thigh.source, None);
    // The read-only viewer sees the change too.
    loop {
        if let ServerMessage::Mapping { entries, .. } = next_json(&mut viewer, WAIT)
            .await
            .expect("mapping broadcast")
        {
            assert!(entries
                .iter()
                .any(|e| e.target == "thigh_l" && e.source.is_none()));
            break;
        }
    }
    let after_cache = cache_contents(&cache_dir);
    assert_ne!(after_cache, before_cache, "the change is cached");
    // The status tells the two clients apart.
    let (_, body) = http_get(addr, "/v1/status").await;
    let status: serde_json::Value = serde_json::from_str(&body).unwrap();
    let kinds: Vec<&str> = status["clients"]["list"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["access"].as_str().unwrap())
        .collect();
    assert!(
        kinds.contains(&"read_only") && kinds.contains(&"control"),
        "{kinds:?}"
    );
    assert!(
        !body.contains(server.control_token().reveal()),
        "no token in the status"
    );
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_listener_beyond_loopback_needs_the_token_to_stream() {
    // All interfaces, but this test only ever connects through loopback.
    let server = rigcast_server::start(ServerConfig {
        listen: "0.0.0.0:0".parse().unwrap(),
        sources: vec![clip_source(fixture_clip())],
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let addr: SocketAddr = format!("127.0.0.1:{}", server.local_addr().port())
        .parse()
        .unwrap();
    let (code, _, mut s) = exchange(addr, &upgrade("/v1/stream", &[])).await;
    assert_eq!(code, 401);
    let mut body = String::new();
    let _ = tokio::time::timeout(WAIT, s.read_to_string(&mut body)).await;
    assert!(body.contains("token"), "{body}");
    assert_eq!(status_code(addr, &get("/v1/status", &[])).await, 401);
    // The viewer's files hold no data: the page loads, and brings its ?token= along.
    assert_eq!(status_code(addr, &get("/", &[])).await, 200);
    let token = server.control_token().reveal().to_string();
    let mut ws = connect(&format!("ws://{addr}/v1/stream?token={token}")).await;
    handshake(&mut ws).await;
    assert!(!collect_frames(&mut ws, Duration::from_millis(300))
        .await
        .is_empty());
    let (head, _) = {
        let raw = get(
            "/v1/status",
            &[("Authorization", &format!("Bearer {token}"))],
        );
        let text = http_raw(addr, raw.as_bytes(), WAIT).await.unwrap();
        let (h, b) = text.split_once("\r\n\r\n").unwrap();
        (h.to_string(), b.to_string())
    };
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frame_over_the_limit_is_refused_on_its_header() {
    let server = start_server(vec![clip_source(fixture_clip())], 30.0, vec![]).await;
    let addr = server.local_addr();
    let (code, _, mut s) = exchange(addr, &upgrade("/v1/stream", &[])).await;
    assert_eq!(code, 101);
    // A masked text frame announcing 16 MB (64-bit length), then nothing more: the server
    // must not wait for (or reserve) the payload.
    let mut header = vec![0x81u8, 0x80 | 127];
    header.extend_from_slice(&(16u64 << 20).to_be_bytes());
    header.extend_from_slice(&[1, 2, 3, 4]);
    s.write_all(&header).await.unwrap();
    // Server frames until the close frame: opcode 0x8, payload starting with the code.
    let close_code = tokio::time::timeout(WAIT, async {
        loop {
            let b0 = s.read_u8().await.unwrap();
            let b1 = s.read_u8().await.unwrap();
            let len = match b1 & 0x7f {
                126 => s.read_u16().await.unwrap() as u64,
                127 => s.read_u64().await.unwrap(),
                n => n as u64,
            };
            let mut payload = vec![0u8; len as usize];
            s.read_exact(&mut payload).await.unwrap();
            if b0 & 0x0f == 0x8 {
                return u16::from_be_bytes([payload[0], payload[1]]);
            }
        }
    })
    .await
    .expect("a close frame within 5 s");
    assert_eq!(close_code, 1009, "message too big");
    // Others are unaffected.
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    server.shutdown().await;
}
