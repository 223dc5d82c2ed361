//! Shutdown stops in order: connected clients are told (close 1001) and their connections are
//! gone before the engine stops; a connection that never sent its request head does not hold
//! the shutdown up; afterwards nothing listens.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use futures_util::StreamExt;
use rigcast_tests::*;
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::Message;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_closes_clients_first_and_does_not_wait_for_idle_sockets() {
    let server = start_demo_server().await;
    let addr = server.local_addr();
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    // A socket that never sends a request: it must not delay the shutdown.
    let idle = tokio::net::TcpStream::connect(addr).await.unwrap();
    let state = server.state().clone();
    let started = Instant::now();
    let stopping = tokio::spawn(server.shutdown());
    let close = loop {
        match tokio::time::timeout(Duration::from_secs(5), ws.next()).await {
            Ok(Some(Ok(Message::Close(frame)))) => break frame,
            Ok(Some(Ok(_))) => continue,
            other => panic!("expected a close frame, got {other:?}"),
        }
    };
    assert_eq!(close.map(|f| f.code), Some(CloseCode::Away));
    drop(ws);
    tokio::time::timeout(Duration::from_secs(10), stopping)
        .await
        .expect("shutdown finished")
        .unwrap();
    assert!(
        started.elapsed() < Duration::from_secs(2),
        "an idle socket held the shutdown for {:?}",
        started.elapsed()
    );
    assert_eq!(state.connections.open(), 0, "connections left open");
    drop(idle);
    assert!(
        tokio::net::TcpStream::connect(addr).await.is_err(),
        "still listening after shutdown"
    );
}
