//! Bad input over the wire gets an `error` reply and the connection keeps working; bad OSC
//! bytes give decoder errors, never panics.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use futures_util::SinkExt;
use rigcast_protocol::control::ErrorCode;
use rigcast_protocol::ServerMessage;
use rigcast_tests::*;
use tokio_tungstenite::tungstenite::Message;

const WAIT: Duration = Duration::from_secs(5);

async fn expect_error(ws: &mut Ws, code: ErrorCode) {
    loop {
        match next_json(ws, WAIT).await {
            Some(ServerMessage::Error {
                code: got, message, ..
            }) => {
                assert_eq!(got, code, "{message}");
                assert!(!message.is_empty());
                return;
            }
            // Status reports arrive about once a second at any point.
            Some(ServerMessage::Lagged { .. } | ServerMessage::SourceStatus { .. }) => continue,
            other => panic!("expected error {code:?}, got {other:?}"),
        }
    }
}

async fn expect_pong(ws: &mut Ws, nonce: u64) {
    send_text(ws, &format!(r#"{{"type":"ping","nonce":{nonce}}}"#)).await;
    loop {
        match next_json(ws, WAIT).await {
            Some(ServerMessage::Pong {
                nonce: got,
                server_nanos,
            }) => {
                assert_eq!(got, nonce);
                assert!(server_nanos > 1_600_000_000_000_000_000);
                return;
            }
            // Status reports arrive about once a second at any point.
            Some(ServerMessage::Lagged { .. } | ServerMessage::SourceStatus { .. }) => continue,
            other => panic!("expected pong, got {other:?}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_messages_get_errors_and_connection_survives() {
    let server = start_server(vec![clip_source(fixture_clip())], 30.0, vec![]).await;
    // set_mapping cases below need a connection with control access.
    let mut ws = connect(&server.control_stream_url()).await;
    handshake(&mut ws).await;
    expect_pong(&mut ws, 1).await;

    let text_cases: Vec<(String, ErrorCode)> = vec![
        ("{not json".into(), ErrorCode::BadJson),
        ("".into(), ErrorCode::BadJson),
        ("42".into(), ErrorCode::MissingType),
        (r#"{"nonce":1}"#.into(), ErrorCode::MissingType),
        (r#"{"type":"teleport"}"#.into(), ErrorCode::UnknownType),
        (r#"{"type":"ping"}"#.into(), ErrorCode::InvalidFields),
        (
            r#"{"type":"ping","nonce":"abc"}"#.into(),
            ErrorCode::InvalidFields,
        ),
        (
            r#"{"type":"subscribe","subjects":"all"}"#.into(),
            ErrorCode::InvalidFields,
        ),
        (
            r#"{"type":"subscribe","subjects":[0,99]}"#.into(),
            ErrorCode::UnknownSubject,
        ),
        (
            r#"{"type":"set_mapping","subject":7,"overrides":{}}"#.into(),
            ErrorCode::UnknownSubject,
        ),
        (
            r#"{"type":"set_mapping","subject":0,"overrides":[1]}"#.into(),
            ErrorCode::InvalidFields,
        ),
        (
            format!(
                r#"{{"type":"ping","nonce":1,"pad":"{}"}}"#,
                "x".repeat(40_000)
            ),
            ErrorCode::MessageTooLarge,
        ),
    ];
    for (i, (text, code)) in text_cases.iter().enumerate() {
        send_text(&mut ws, text).await;
        expect_error(&mut ws, *code).await;
        expect_pong(&mut ws, 100 + i as u64).await;
    }

    ws.send(Message::binary(vec![1u8, 2, 3])).await.unwrap();
    expect_error(&mut ws, ErrorCode::BinaryNotAccepted).await;
    expect_pong(&mut ws, 200).await;

    // set_mapping on a source subject is refused (the valid case is in engine_performers).
    send_text(
        &mut ws,
        r#"{"type":"set_mapping","subject":0,"overrides":{"tail1":null,"head":"body"}}"#,
    )
    .await;
    // Subject 0 is a source: mappings belong to target subjects.
    expect_error(&mut ws, ErrorCode::Unsupported).await;

    // Frames still flow after all that.
    let frames = collect_frames(&mut ws, Duration::from_millis(300)).await;
    assert!(!frames.is_empty());

    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn subscribe_filters_subjects() {
    let mut second = fixture_clip();
    second.name = "second".into();
    let server = start_server(
        vec![clip_source(fixture_clip()), clip_source(second)],
        30.0,
        vec![],
    )
    .await;
    let mut ws = connect(&server.stream_url()).await;
    let (_, skeletons) = handshake(&mut ws).await;
    assert_eq!(skeletons.len(), 2);
    let both = collect_frames(&mut ws, Duration::from_millis(400)).await;
    assert!(both.iter().any(|(f, _)| f.header.subject == 0));
    assert!(both.iter().any(|(f, _)| f.header.subject == 1));
    send_text(&mut ws, r#"{"type":"subscribe","subjects":[1]}"#).await;
    // Let frames already queued before the subscribe drain.
    collect_frames(&mut ws, Duration::from_millis(200)).await;
    let only = collect_frames(&mut ws, Duration::from_millis(400)).await;
    assert!(!only.is_empty());
    assert!(only.iter().all(|(f, _)| f.header.subject == 1));
    server.shutdown().await;
}

#[test]
fn bad_osc_bytes_give_errors_not_panics() {
    use rigcast_protocol::vmc::decode_packet;
    let mut cases: Vec<Vec<u8>> = vec![
        vec![],
        b"/VMC/Ext/Bone/Pos".to_vec(),
        b"#bundle\0\0\0\0\0\0\0\0\x01\0\0\0\x10".to_vec(),
        vec![0x2f; 3],
    ];
    // Deterministic pseudo-random garbage (xorshift), including valid-looking prefixes.
    let mut x: u32 = 0x1234_5678;
    for len in 0..200usize {
        let mut v = if len % 2 == 0 {
            b"#bundle\0".to_vec()
        } else {
            b"/VMC/Ext/".to_vec()
        };
        for _ in 0..len {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            v.push(x as u8);
        }
        cases.push(v);
    }
    for c in &cases {
        // Either an error or a (possibly empty) list; never a panic.
        let _ = decode_packet(c);
    }
    assert!(decode_packet(&cases[0]).is_err());
    assert!(decode_packet(&cases[1]).is_err());
    assert!(decode_packet(&cases[2]).is_err());
}
