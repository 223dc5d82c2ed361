//! One task per WebSocket client: greets it, forwards the frames it subscribed to, answers its
//! requests, and survives both its mistakes and its slowness.
//!
//! Slowness: the task is the only thing that awaits the client's socket. When the client stops
//! reading, this task blocks in `send`, stops draining its `broadcast` receiver, and falls
//! behind; the tick is unaffected. When it catches up, `recv` returns `Lagged(n)`: the client
//! gets a `lagged` message and the next binary frame carries `missed_frames = n`.
//!
//! Mistakes: bad JSON, unknown types, bad fields, binary messages and oversize messages are
//! answered with an `error` message; the connection stays open.

use std::collections::HashSet;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use futures_util::{SinkExt, StreamExt};
use rigcast_protocol::control::{parse_client_message, ClientMessage, ErrorCode};
use rigcast_protocol::frame::set_missed_frames;
use rigcast_protocol::ServerMessage;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::{Bytes, Message};
use tokio_tungstenite::WebSocketStream;

use crate::engine::{unix_nanos, EngineCommand};
use crate::state::ServerState;
use crate::stats::ClientStats;

/// Largest client message the server reads (control messages are tiny). Larger messages up to
/// the transport limit are answered with `message_too_large`; beyond it the WebSocket layer
/// closes the connection.
pub const MAX_CLIENT_MESSAGE_BYTES: usize = 64 * 1024;
/// Transport limit given to tungstenite.
pub const MAX_TRANSPORT_MESSAGE_BYTES: usize = 16 * 1024 * 1024;

/// Serves one upgraded connection until it closes or the server shuts down.
pub async fn serve_client<S>(ws: WebSocketStream<S>, state: Arc<ServerState>, peer: String)
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let client_id = state.next_client_id.fetch_add(1, Ordering::Relaxed);
    let stats = Arc::new(ClientStats {
        peer,
        ..ClientStats::default()
    });
    if let Ok(mut clients) = state.stats.clients.lock() {
        clients.insert(client_id, stats.clone());
    }
    // Subscribe before greeting so no frame or event published after `hello` is missed.
    let mut frames = state.frames.subscribe();
    let mut events = state.events.subscribe();
    let _ = run(ws, &state, &stats, &mut frames, &mut events).await;
    if let Ok(mut clients) = state.stats.clients.lock() {
        clients.remove(&client_id);
    }
}

async fn run<S>(
    ws: WebSocketStream<S>,
    state: &ServerState,
    stats: &ClientStats,
    frames: &mut tokio::sync::broadcast::Receiver<crate::engine::OutFrame>,
    events: &mut tokio::sync::broadcast::Receiver<String>,
) -> Result<(), tokio_tungstenite::tungstenite::Error>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let (mut sink, mut stream) = ws.split();
    sink.send(Message::text(state.hello_json())).await?;
    for s in state.subjects.iter() {
        sink.send(Message::text(s.shape().skeleton_json.clone()))
            .await?;
    }
    for s in state.subjects.iter() {
        let mapping = s.mapping_json.read().ok().and_then(|m| m.clone());
        if let Some(m) = mapping {
            sink.send(Message::text(m)).await?;
        }
    }
    sink.send(Message::text(crate::source_status_json(&state.subjects)))
        .await?;
    // `None` = all subjects.
    let mut subscribed: Option<HashSet<u32>> = None;
    // Frame version; version 1 until the client asks for another (`set_protocol`).
    let mut version = rigcast_protocol::PROTOCOL_VERSION;
    let mut pending_missed: u64 = 0;
    let mut shutdown = state.shutdown.clone();
    loop {
        tokio::select! {
            biased;
            _ = shutdown.changed() => {
                let _ = sink.send(Message::Close(None)).await;
                return Ok(());
            }
            // Before frames, so a new skeleton arrives before frames that use it.
            event = events.recv() => {
                match event {
                    Ok(text) => sink.send(Message::text(text)).await?,
                    // Control messages are small and rare; a client this far behind will
                    // also lag on frames and be told so there.
                    Err(RecvError::Lagged(_)) => {}
                    Err(RecvError::Closed) => return Ok(()),
                }
            }
            incoming = stream.next() => {
                let Some(incoming) = incoming else { return Ok(()) };
                let reply = match incoming {
                    Ok(Message::Text(text)) => {
                        handle_text(text.as_str(), state, &mut subscribed, &mut version)
                    }
                    Ok(Message::Binary(b)) => Some(ServerMessage::error(
                        ErrorCode::BinaryNotAccepted,
                        format!("clients send JSON text messages only; got {} binary bytes", b.len()),
                    )),
                    Ok(Message::Close(_)) => return Ok(()),
                    // Pings are answered by tungstenite itself.
                    Ok(_) => None,
                    Err(e) => return Err(e),
                };
                if let Some(reply) = reply {
                    sink.send(Message::text(reply.to_json())).await?;
                }
            }
            received = frames.recv() => {
                match received {
                    Ok(frame) => {
                        if let Some(set) = &subscribed {
                            if !set.contains(&frame.subject) {
                                continue;
                            }
                        }
                        let bytes = frame.version(version);
                        if bytes.is_empty() {
                            continue; // no frame of this version this tick
                        }
                        let bytes = if pending_missed > 0 {
                            // Personalise the shared frame: only after a lag, so rare.
                            let mut own = bytes.to_vec();
                            set_missed_frames(&mut own, pending_missed.min(u32::MAX as u64) as u32);
                            pending_missed = 0;
                            Bytes::from(own)
                        } else {
                            bytes
                        };
                        sink.send(Message::Binary(bytes)).await?;
                        stats.frames_sent.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(RecvError::Lagged(n)) => {
                        pending_missed += n;
                        stats.missed_frames.fetch_add(n, Ordering::Relaxed);
                        state.stats.dropped_frames.fetch_add(n, Ordering::Relaxed);
                        sink.send(Message::text(ServerMessage::Lagged { missed: n }.to_json())).await?;
                    }
                    Err(RecvError::Closed) => return Ok(()),
                }
            }
        }
    }
}

fn handle_text(
    text: &str,
    state: &ServerState,
    subscribed: &mut Option<HashSet<u32>>,
    version: &mut u16,
) -> Option<ServerMessage> {
    if text.len() > MAX_CLIENT_MESSAGE_BYTES {
        return Some(ServerMessage::error(
            ErrorCode::MessageTooLarge,
            format!(
                "message of {} bytes exceeds the {MAX_CLIENT_MESSAGE_BYTES}-byte limit",
                text.len()
            ),
        ));
    }
    let msg = match parse_client_message(text) {
        Ok(m) => m,
        Err(e) => return Some(ServerMessage::error(e.code, e.message)),
    };
    match msg {
        ClientMessage::Ping { nonce } => Some(ServerMessage::Pong {
            nonce,
            server_nanos: unix_nanos(),
        }),
        ClientMessage::SetProtocol { version: wanted } => {
            Some(if rigcast_protocol::PROTOCOL_VERSIONS.contains(&wanted) {
                *version = wanted;
                ServerMessage::Protocol { version: wanted }
            } else {
                ServerMessage::error(
                    ErrorCode::Unsupported,
                    format!(
                        "protocol version {wanted} is not supported; this server speaks {:?}",
                        rigcast_protocol::PROTOCOL_VERSIONS
                    ),
                )
            })
        }
        ClientMessage::Subscribe { subjects: None } => {
            *subscribed = None;
            None
        }
        ClientMessage::Subscribe {
            subjects: Some(ids),
        } => {
            let unknown: Vec<u32> = ids
                .iter()
                .copied()
                .filter(|id| state.subject(*id).is_none())
                .collect();
            if !unknown.is_empty() {
                return Some(ServerMessage::error(
                    ErrorCode::UnknownSubject,
                    format!("unknown subject id(s) {unknown:?}; subscription unchanged"),
                ));
            }
            *subscribed = Some(ids.into_iter().collect());
            None
        }
        ClientMessage::Calibrate {
            subject,
            pose,
            delay_secs,
        } => Some(
            match crate::calibration::start(
                &state.subjects,
                &state.events,
                subject,
                pose,
                delay_secs,
            ) {
                Ok(()) => ServerMessage::Ack {
                    request: "calibrate".into(),
                    subject,
                },
                Err((code, message)) => ServerMessage::error(code, message),
            },
        ),
        ClientMessage::SetMapping { subject, overrides } => {
            let Some(target) = state.subject(subject) else {
                return Some(ServerMessage::error(
                    ErrorCode::UnknownSubject,
                    format!("unknown subject id {subject}"),
                ));
            };
            if let Err(message) = check_overrides(state, target, &overrides) {
                return Some(ServerMessage::error(ErrorCode::Unsupported, message));
            }
            match state
                .commands
                .try_send(EngineCommand::SetMapping { subject, overrides })
            {
                Ok(()) => Some(ServerMessage::Ack {
                    request: "set_mapping".into(),
                    subject,
                }),
                Err(mpsc::error::TrySendError::Full(_)) => Some(ServerMessage::error(
                    ErrorCode::Internal,
                    "engine is busy; retry",
                )),
                Err(mpsc::error::TrySendError::Closed(_)) => Some(ServerMessage::error(
                    ErrorCode::Internal,
                    "engine is shutting down",
                )),
            }
        }
    }
}

/// Checks `set_mapping` overrides against the target's and its sources' skeletons, so a typo
/// is answered at once instead of failing later in the mapper.
fn check_overrides(
    state: &ServerState,
    target: &crate::engine::Subject,
    overrides: &std::collections::BTreeMap<String, Option<String>>,
) -> Result<(), String> {
    if !target.is_target() {
        return Err(format!(
            "subject {} is a source; set_mapping applies to target subjects",
            target.id
        ));
    }
    let tsk = target.skeleton();
    let sources: Vec<_> = target
        .inputs
        .iter()
        .filter_map(|id| state.subject(*id).map(|s| s.skeleton()))
        .collect();
    let refs: Vec<&rigcast_retarget::Skeleton> = sources.iter().map(|s| &**s).collect();
    for (t, s) in overrides {
        if tsk.bone(t).is_none() {
            return Err(format!("target subject {} has no bone {t:?}", target.id));
        }
        if let Some(s) = s {
            if crate::mapper::find_source_bone(&refs, s).is_none() {
                return Err(format!(
                    "no source of target subject {} has a bone {s:?}",
                    target.id
                ));
            }
        }
    }
    Ok(())
}
