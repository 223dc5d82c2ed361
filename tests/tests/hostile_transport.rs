//! Hostile HTTP and WebSocket input to the real `rigcast serve` binary: repeated deciding
//! headers, header lines other parsers read differently, foreign WebSocket versions, protocol violations (answered with their close codes),
//! oversized text quoted back in errors, and clients that request a model file and never read.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::time::Duration;

use rigcast_tests::*;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const PROMPT: Duration = Duration::from_secs(5);

fn serve(name: &str, args: &[&str]) -> ServeProcess {
    let mut all = vec!["--source", "demo"];
    all.extend_from_slice(args);
    ServeProcess::start(&all, temp_path(name), None)
}

/// Connects and completes a WebSocket handshake by hand; returns the socket after the 101.
async fn raw_upgrade(addr: SocketAddr) -> TcpStream {
    let mut s = TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "GET /v1/stream HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    // Read the 101 head byte by byte so no frame after it is consumed.
    let mut got = Vec::new();
    while !got.ends_with(b"\r\n\r\n") {
        let mut b = [0u8; 1];
        s.read_exact(&mut b).await.unwrap();
        got.push(b[0]);
    }
    assert!(
        got.starts_with(b"HTTP/1.1 101"),
        "{}",
        String::from_utf8_lossy(&got)
    );
    s
}

/// A masked client frame.
fn client_frame(first_byte: u8, payload: &[u8]) -> Vec<u8> {
    let mask = [1u8, 2, 3, 4];
    let mut f = vec![first_byte];
    assert!(payload.len() < 126);
    f.push(0x80 | payload.len() as u8);
    f.extend_from_slice(&mask);
    f.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
    f
}

/// Reads server frames until a close frame; its status code (`None`: the connection ended
/// without one).
async fn close_code(s: &mut TcpStream) -> Option<u16> {
    let read = async {
        loop {
            let mut h = [0u8; 2];
            s.read_exact(&mut h).await.ok()?;
            let mut len = (h[1] & 0x7f) as u64;
            if len == 126 {
                let mut b = [0u8; 2];
                s.read_exact(&mut b).await.ok()?;
                len = u16::from_be_bytes(b) as u64;
            } else if len == 127 {
                let mut b = [0u8; 8];
                s.read_exact(&mut b).await.ok()?;
                len = u64::from_be_bytes(b);
            }
            let mut payload = vec![0u8; len as usize];
            s.read_exact(&mut payload).await.ok()?;
            if h[0] & 0x0f == 0x8 {
                return payload.get(..2).map(|c| u16::from_be_bytes([c[0], c[1]]));
            }
        }
    };
    tokio::time::timeout(PROMPT, read).await.ok().flatten()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn protocol_violations_are_closed_with_their_codes() {
    let server = serve("hostile_ws_home", &[]);
    // Reserved bits set: a protocol error, 1002.
    let mut s = raw_upgrade(server.addr).await;
    s.write_all(&client_frame(0x80 | 0x40 | 0x1, b"{}"))
        .await
        .unwrap();
    assert_eq!(close_code(&mut s).await, Some(1002));
    // An unmasked client frame: 1002 too.
    let mut s = raw_upgrade(server.addr).await;
    s.write_all(&[0x81, 2, b'{', b'}']).await.unwrap();
    assert_eq!(close_code(&mut s).await, Some(1002));
    // Text that is not UTF-8: 1007.
    let mut s = raw_upgrade(server.addr).await;
    s.write_all(&client_frame(0x81, b"{\"type\":\"\xff\xfe\"}"))
        .await
        .unwrap();
    assert_eq!(close_code(&mut s).await, Some(1007));
    // The server streams on for a well-behaved client.
    let mut ws = connect(&format!("ws://{}/v1/stream", server.addr)).await;
    handshake(&mut ws).await;
    assert!(!collect_frames(&mut ws, Duration::from_millis(500))
        .await
        .is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn repeated_hosts_and_foreign_websocket_versions_are_refused() {
    let server = serve("hostile_http_home", &[]);
    let addr = server.addr;
    // Two Hosts: which one an access check saw would be up to the parser; refused.
    let both = format!("GET /v1/status HTTP/1.1\r\nHost: {addr}\r\nHost: evil.example\r\n\r\n");
    let got = http_raw(addr, both.as_bytes(), PROMPT).await.unwrap();
    assert!(got.starts_with("HTTP/1.1 400"), "{got}");
    assert!(got.contains("more than one Host"), "{got}");
    let reversed = format!("GET /v1/status HTTP/1.1\r\nHost: evil.example\r\nHost: {addr}\r\n\r\n");
    let got = http_raw(addr, reversed.as_bytes(), PROMPT).await.unwrap();
    assert!(got.starts_with("HTTP/1.1 400"), "{got}");
    // A WebSocket version other than 13: 426, naming 13.
    for version in ["8", "", "13, 8"] {
        let head = format!(
            "GET /v1/stream HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
             Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: {version}\r\n\r\n"
        );
        let got = http_raw(addr, head.as_bytes(), PROMPT).await.unwrap();
        assert!(got.starts_with("HTTP/1.1 426"), "{version:?}: {got}");
        assert!(got.contains("Sec-WebSocket-Version: 13"), "{got}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn header_lines_a_proxy_could_read_differently_are_refused() {
    let server = serve("hostile_http_lines", &[]);
    let addr = server.addr;
    // Each hides a second Host from one reader or the other: folded onto the previous line,
    // space before the colon, a bare LF or CR inside a line; and a request line with extra parts.
    for (what, head) in [
        (
            "folded",
            format!(
                "GET /v1/status HTTP/1.1\r\nHost: {addr}\r\nX-A: 1\r\n Host: evil.example\r\n\r\n"
            ),
        ),
        (
            "space before colon",
            format!("GET /v1/status HTTP/1.1\r\nHost : evil.example\r\nHost: {addr}\r\n\r\n"),
        ),
        (
            "bare LF",
            format!(
                "GET /v1/status HTTP/1.1\r\nX-A: 1\nHost: evil.example\r\nHost: {addr}\r\n\r\n"
            ),
        ),
        (
            "bare CR",
            format!(
                "GET /v1/status HTTP/1.1\r\nX-A: 1\rHost: evil.example\r\nHost: {addr}\r\n\r\n"
            ),
        ),
        (
            "no colon",
            format!("GET /v1/status HTTP/1.1\r\nHost: {addr}\r\nHost evil.example\r\n\r\n"),
        ),
        (
            "request line",
            format!("GET /v1/status HTTP/1.1 extra\r\nHost: {addr}\r\n\r\n"),
        ),
    ] {
        let got = http_raw(addr, head.as_bytes(), PROMPT).await.unwrap();
        assert!(got.starts_with("HTTP/1.1 400"), "{what}: {got}");
    }
    // The same request, well formed, is served.
    let plain = format!("GET /v1/status HTTP/1.1\r\nHost: {addr}\r\nX-A: 1\r\n\r\n");
    let got = http_raw(addr, plain.as_bytes(), PROMPT).await.unwrap();
    assert!(got.starts_with("HTTP/1.1 200"), "{got}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn errors_quote_only_a_short_prefix_of_the_input() {
    let server = serve("hostile_echo_home", &[]);
    let addr = server.addr;
    // A 15 KB Host (just under the head limit) is refused without being echoed whole.
    let host = "h".repeat(15_000);
    let raw = format!("GET /v1/status HTTP/1.1\r\nHost: {host}\r\n\r\n");
    let got = http_raw(addr, raw.as_bytes(), PROMPT).await.unwrap();
    assert!(got.starts_with("HTTP/1.1 403"), "{}", &got[..100]);
    assert!(got.len() < 1_000, "{} bytes answered", got.len());
    // A 60 KB message type over WebSocket: the error quotes a prefix.
    let mut ws = connect(&format!("ws://{addr}/v1/stream")).await;
    handshake(&mut ws).await;
    let kind = "k".repeat(60_000);
    send_text(&mut ws, &format!("{{\"type\":\"{kind}\"}}")).await;
    send_text(
        &mut ws,
        &format!("{{\"type\":\"subscribe\",\"subjects\":\"{kind}\"}}"),
    )
    .await;
    let mut errors = Vec::new();
    while errors.len() < 2 {
        match next_json(&mut ws, PROMPT).await.expect("an error reply") {
            rigcast_protocol::ServerMessage::Error { message, .. } => errors.push(message),
            _ => continue,
        }
    }
    for e in errors {
        assert!(e.len() < 600, "{} characters: {}…", e.len(), &e[..80]);
    }
}

/// A GLB target grown to `bytes` by padding its JSON chunk with spaces (still valid glTF):
/// made from a small BVH by `rigcast convert`, so no outside file is needed.
fn big_glb(bytes: usize) -> std::path::PathBuf {
    let dir = temp_path("hostile_model");
    std::fs::create_dir_all(&dir).unwrap();
    let bvh = dir.join("rig.bvh");
    std::fs::write(
        &bvh,
        "HIERARCHY\nROOT Hips\n{\nOFFSET 0 1 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n\
         JOINT Spine\n{\nOFFSET 0 0.3 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{\nOFFSET 0 0.3 0\n}\n}\n}\n\
         MOTION\nFrames: 1\nFrame Time: 0.0333\n0 1 0 0 0 0 0 0 0\n",
    )
    .unwrap();
    let small = dir.join("rig_small.glb");
    let out = std::process::Command::new(rigcast_binary())
        .args(["convert", bvh.to_str().unwrap(), small.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let glb = std::fs::read(&small).unwrap();
    let u32_at = |i: usize| u32::from_le_bytes(glb[i..i + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let mut json = glb[20..20 + json_len].to_vec();
    let rest = &glb[20 + json_len..];
    json.resize(json.len() + bytes, b' ');
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + json.len() + rest.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(rest);
    let path = dir.join("rig_big.glb");
    std::fs::write(&path, out).unwrap();
    path
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn model_requests_that_are_never_read_hold_little_memory() {
    const MODEL_BYTES: usize = 20 << 20;
    const CLIENTS: usize = 50;
    let glb = big_glb(MODEL_BYTES);
    let server = serve("hostile_model_home", &["--target", glb.to_str().unwrap()]);
    let addr = server.addr;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let before = server.rss_kib();
    let mut held = Vec::new();
    for _ in 0..CLIENTS {
        let mut s = TcpStream::connect(addr).await.unwrap();
        let req = format!("GET /v1/subjects/1/model.glb HTTP/1.1\r\nHost: {addr}\r\n\r\n");
        s.write_all(req.as_bytes()).await.unwrap();
        held.push(s);
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let grown_kib = server.rss_kib().saturating_sub(before);
    // Whole-file reads would hold CLIENTS × 20 MB = 1 GB; a chunk each is a few MB.
    assert!(
        grown_kib < 64 * 1024,
        "{CLIENTS} unread model requests grew the server by {grown_kib} KiB"
    );
    // And a client that reads gets the whole file.
    drop(held);
    let raw = format!("GET /v1/subjects/1/model.glb HTTP/1.1\r\nHost: {addr}\r\n\r\n");
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(raw.as_bytes()).await.unwrap();
    let mut body = Vec::new();
    tokio::time::timeout(Duration::from_secs(30), s.read_to_end(&mut body))
        .await
        .unwrap()
        .unwrap();
    let at = body.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
    assert_eq!(
        body.len() - at,
        std::fs::metadata(&glb).unwrap().len() as usize
    );
    assert!(body[at..].starts_with(b"glTF"));
}
