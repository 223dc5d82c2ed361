//! The hand-parsed HTTP listener under bad input: every malformed or hostile request gets a
//! prompt, well-formed answer (or a closed connection) and never stalls the tick or other
//! clients.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use rigcast_tests::*;
use tokio::io::AsyncWriteExt;

/// Far below the server's 10 s head timeout: every answer below must come without it.
const PROMPT: Duration = Duration::from_secs(3);

async fn status_line(addr: std::net::SocketAddr, raw: &[u8]) -> String {
    let text = http_raw(addr, raw, PROMPT)
        .await
        .unwrap_or_else(|| panic!("connection reset for {:?}", String::from_utf8_lossy(raw)));
    text.lines().next().unwrap_or_default().to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_requests_get_clear_answers() {
    let server = start_server(vec![clip_source(fixture_clip())], 30.0, vec![]).await;
    let addr = server.local_addr();
    let cases: &[(&[u8], &str)] = &[
        // Request line without a target.
        (b"GET\r\n\r\n", "HTTP/1.1 400"),
        (b"\r\n\r\n", "HTTP/1.1 400"),
        (
            b"POST /v1/status HTTP/1.1\r\nHost: x\r\n\r\n",
            "HTTP/1.1 405",
        ),
        (b"DELETE / HTTP/1.1\r\n\r\n", "HTTP/1.1 405"),
        // The viewer files are embedded: no path reaches the file system.
        (b"GET /../../etc/passwd HTTP/1.1\r\n\r\n", "HTTP/1.1 404"),
        (
            b"GET /%2e%2e/%2e%2e/etc/passwd HTTP/1.1\r\n\r\n",
            "HTTP/1.1 404",
        ),
        (b"GET /..%2findex.html HTTP/1.1\r\n\r\n", "HTTP/1.1 404"),
        // Not UTF-8 in the path and in a header.
        (b"GET /\xff\xfe HTTP/1.1\r\n\r\n", "HTTP/1.1 404"),
        (
            b"GET /v1/status HTTP/1.1\r\nX-Junk: \xc3\x28\r\n\r\n",
            "HTTP/1.1 200",
        ),
        // HTTP/1.0, no Host header: still served.
        (b"GET /v1/status HTTP/1.0\r\n\r\n", "HTTP/1.1 200"),
        (b"GET / HTTP/1.1\r\n\r\n", "HTTP/1.1 200"),
        // A bogus upgrade: no key.
        (
            b"GET /v1/stream HTTP/1.1\r\nUpgrade: websocket\r\n\r\n",
            "HTTP/1.1 426",
        ),
    ];
    for (raw, want) in cases {
        let got = status_line(addr, raw).await;
        assert!(
            got.starts_with(want),
            "{:?}: expected {want}, got {got:?}",
            String::from_utf8_lossy(raw)
        );
    }

    // A head over the 16 KiB limit: refused (431) or the connection closed, at once.
    let mut huge = b"GET / HTTP/1.1\r\n".to_vec();
    for i in 0..400 {
        huge.extend_from_slice(format!("X-Filler-{i}: {}\r\n", "y".repeat(60)).as_bytes());
    }
    huge.extend_from_slice(b"\r\n");
    let t0 = Instant::now();
    if let Some(text) = http_raw(addr, &huge, PROMPT).await {
        assert!(
            text.is_empty() || text.starts_with("HTTP/1.1 431"),
            "{text:.80}"
        );
    }
    assert!(t0.elapsed() < PROMPT);
    // The same bytes without the final blank line (never completes): still answered at once.
    huge.truncate(huge.len() - 2);
    if let Some(text) = http_raw(addr, &huge, PROMPT).await {
        assert!(
            text.is_empty() || text.starts_with("HTTP/1.1 431"),
            "{text:.80}"
        );
    }

    // After all that the server still answers.
    let (head, _) = http_get(addr, "/v1/status").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    server.shutdown().await;
}

/// Clients that open a connection and never finish their request (slowloris) hold neither
/// the tick nor other clients.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unfinished_requests_do_not_stall_others() {
    let server = start_server(vec![clip_source(fixture_clip())], 30.0, vec![]).await;
    let addr = server.local_addr();
    let mut stalled = Vec::new();
    for i in 0..20 {
        let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
        // Half a request line, or a full line and a header with no blank line.
        let partial: &[u8] = if i % 2 == 0 {
            b"GET /v1/sta"
        } else {
            b"GET /v1/status HTTP/1.1\r\nHost: x\r\n"
        };
        s.write_all(partial).await.unwrap();
        stalled.push(s);
    }
    // A WebSocket client still gets a steady stream...
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    let frames = collect_frames(&mut ws, Duration::from_millis(1000)).await;
    let seqs: std::collections::BTreeSet<u64> = frames.iter().map(|(f, _)| f.header.seq).collect();
    // The 30 fps replay advances ~30 frames a second; a stalled server would show one or none.
    assert!(
        seqs.len() >= 10,
        "only {} distinct frames in 1 s",
        seqs.len()
    );
    // ...and plain requests are answered promptly.
    let t0 = Instant::now();
    let (head, _) = http_get(addr, "/v1/status").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(t0.elapsed() < PROMPT, "status took {:?}", t0.elapsed());
    // The stalled connections are closed by the head timeout, not kept forever.
    let mut s = stalled.pop().unwrap();
    let mut buf = [0u8; 64];
    let closed = tokio::time::timeout(Duration::from_secs(15), async {
        use tokio::io::AsyncReadExt;
        loop {
            match s.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(_) => {}
            }
        }
    })
    .await;
    assert!(
        closed.is_ok(),
        "an unfinished request was kept open past 15 s"
    );
    server.shutdown().await;
}
