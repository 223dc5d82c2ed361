//! One task per WebSocket client: greets it, forwards the frames it subscribed to, answers its
//! requests, and survives both its mistakes and its slowness.
//!
//! Slowness: the task is the only thing that awaits the client's socket. When the client stops
//! reading, this task blocks in `send`, stops draining its `broadcast` receiver, and falls
//! behind; the tick is unaffected. When it catches up, `recv` returns `Lagged(n)`: the client
//! gets a `lagged` message and the next binary frame carries `missed_frames = n`.
//!
//! Mistakes: bad JSON, unknown types, bad fields, binary messages and oversize messages are
//! answered with an `error` message; the connection stays open. A frame over the transport
//! limit closes it (1009), refused on its header before its payload is buffered.
//!
//! Stalls: a client whose socket accepts nothing for the stall timeout (it never reads) is
//! dropped; one that reads, however slowly, stays.
//!
//! Control messages: frames may be dropped for a lagging client, control messages may not.
//! When the client's control queue (`events`) overflows, the queue is discarded and the
//! client gets a fresh snapshot of the state those messages describe — `subjects_changed`,
//! every `skeleton`, every `mapping`, `source_status` — before its next frame.
//!
//! Access: messages that change the server (`set_mapping`, `calibrate`, `set_performer`)
//! need a connection opened with the control token ([`Access::Control`]); others are
//! answered `unauthorized`. In cluster mode such a message about another node's subject is
//! forwarded to that node ([`crate::cluster::Forwarder`]), which checks the token again, and
//! its answer arrives later through the session's reply queue.

use std::collections::HashSet;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use futures_util::stream::SplitSink;
use futures_util::{SinkExt, StreamExt};
use rigcast_protocol::control::{parse_client_message, ClientMessage, ErrorCode};
use rigcast_protocol::frame::set_missed_frames;
use rigcast_protocol::ServerMessage;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::sync::broadcast::error::{RecvError, TryRecvError};
use tokio::sync::{broadcast, mpsc};
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::protocol::CloseFrame;
use tokio_tungstenite::tungstenite::{Bytes, Message};
use tokio_tungstenite::WebSocketStream;

use crate::access::Access;
use crate::changes::type_name;
use crate::state::Sessions;
use crate::stats::ClientStats;
use crate::wire;
use rigcast_engine::clock::unix_nanos;
use rigcast_engine::events::Event;

/// Largest client message the server interprets (control messages are small JSON). Larger
/// ones up to the transport limit are answered with `message_too_large`.
pub const MAX_CLIENT_MESSAGE_BYTES: usize = 32 * 1024;
/// Transport limit given to tungstenite, per frame and per message: beyond it the connection
/// is closed with 1009. Small, so that the connection cap times this stays modest memory.
pub const MAX_TRANSPORT_MESSAGE_BYTES: usize = 64 * 1024;

/// Why a session ended early (a clean end is `Ok`).
enum End {
    /// The client's socket accepted nothing for the stall timeout.
    Stalled,
    /// The WebSocket layer failed (protocol error, reset): nothing more to tell the client.
    Transport,
}

type Sink<S> = SplitSink<WebSocketStream<S>, Message>;

/// Runs one write operation on the sink, giving up after `stall`: a client that reads nothing
/// at all must not hold its task (and its buffers) forever.
async fn within<F, E>(stall: Duration, op: F) -> Result<(), End>
where
    F: std::future::Future<Output = Result<(), E>>,
{
    match tokio::time::timeout(stall, op).await {
        Ok(Ok(())) => Ok(()),
        Ok(Err(_)) => Err(End::Transport),
        Err(_) => Err(End::Stalled),
    }
}

/// Sends one message (see [`within`]).
async fn send<S>(sink: &mut Sink<S>, msg: Message, stall: Duration) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    within(stall, sink.send(msg)).await
}

/// Queues one message without writing it yet (see [`flush`]).
async fn feed<S>(sink: &mut Sink<S>, msg: Message, stall: Duration) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    within(stall, sink.feed(msg)).await
}

/// Writes what [`feed`] queued.
async fn flush<S>(sink: &mut Sink<S>, stall: Duration) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    within(stall, sink.flush()).await
}

/// Requests a session may have waiting for other nodes' answers at once.
const MAX_FORWARDS_IN_FLIGHT: usize = 8;

/// Frames sent in one write at most (a tick makes one per subject).
const MAX_FRAMES_PER_WRITE: usize = 32;

/// The next frame already queued for this client, if any (never waits).
fn next_queued(
    frames: &mut broadcast::Receiver<rigcast_engine::tick::OutFrame>,
) -> Option<Result<rigcast_engine::tick::OutFrame, RecvError>> {
    match frames.try_recv() {
        Ok(f) => Some(Ok(f)),
        Err(TryRecvError::Lagged(n)) => Some(Err(RecvError::Lagged(n))),
        Err(TryRecvError::Empty | TryRecvError::Closed) => None,
    }
}

/// The shared frame, or after a lag a copy carrying the frames this client missed (rare).
fn personalise(bytes: Bytes, pending_missed: &mut u64) -> Bytes {
    if *pending_missed == 0 {
        return bytes;
    }
    let mut own = bytes.to_vec();
    set_missed_frames(&mut own, (*pending_missed).min(u64::from(u32::MAX)) as u32);
    *pending_missed = 0;
    Bytes::from(own)
}

/// Serves one upgraded connection until it closes or the server shuts down.
pub async fn serve_client<S>(
    ws: WebSocketStream<S>,
    shared: Sessions,
    client_id: u64,
    peer: String,
    access: Access,
) where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let stats = Arc::new(ClientStats::new(peer, access));
    if let Ok(mut clients) = shared.feeds.stats.clients.lock() {
        clients.insert(client_id, stats.clone());
    }
    // Subscribe before greeting so no frame or event published after `hello` is missed.
    let mut frames = shared.feeds.frames.subscribe();
    let mut events = shared.feeds.events.subscribe();
    if let Err(End::Stalled) = run(ws, &shared, &stats, &mut frames, &mut events).await {
        shared
            .feeds
            .stats
            .stalled_disconnects
            .fetch_add(1, Ordering::Relaxed);
    }
    if let Ok(mut clients) = shared.feeds.stats.clients.lock() {
        clients.remove(&client_id);
    }
}

/// After the control queue overflowed: drops what is left of it (all older than what is
/// about to be read from the state) and sends the current state instead.
async fn resync<S>(
    sink: &mut Sink<S>,
    events: &mut broadcast::Receiver<Event>,
    shared: &Sessions,
    stats: &ClientStats,
) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    // Bounded: the queue holds at most its capacity, newer messages are dropped for a lag
    // that the next recv reports (and resyncs) again.
    for _ in 0..rigcast_engine::events::EVENTS_CAPACITY * 2 {
        match events.try_recv() {
            Ok(_) | Err(TryRecvError::Lagged(_)) => {}
            Err(TryRecvError::Empty | TryRecvError::Closed) => break,
        }
    }
    stats.control_resyncs.fetch_add(1, Ordering::Relaxed);
    shared
        .feeds
        .stats
        .control_resyncs
        .fetch_add(1, Ordering::Relaxed);
    let subjects = ServerMessage::SubjectsChanged {
        subjects: shared.subject_infos(),
    }
    .to_json();
    send(sink, Message::text(subjects), shared.stalled_client_timeout).await?;
    send_state(sink, shared).await
}

/// Sends a control event as its protocol message, or the state after the queue overflowed;
/// `false` once the queue is closed (shutdown).
async fn on_event<S>(
    sink: &mut Sink<S>,
    event: Result<Event, RecvError>,
    events: &mut broadcast::Receiver<Event>,
    shared: &Sessions,
    stats: &ClientStats,
) -> Result<bool, End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    match event {
        Ok(event) => {
            let text = wire::message(&event).to_json();
            send(sink, Message::text(text), shared.stalled_client_timeout).await?;
        }
        Err(RecvError::Lagged(_)) => resync(sink, events, shared, stats).await?,
        Err(RecvError::Closed) => return Ok(false),
    }
    Ok(true)
}

/// Sends the state that control messages describe (see [`wire::state_messages`]).
async fn send_state<S>(sink: &mut Sink<S>, shared: &Sessions) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    for message in wire::state_messages(&shared.feeds.subjects()) {
        let text = Message::text(message.to_json());
        send(sink, text, shared.stalled_client_timeout).await?;
    }
    Ok(())
}

/// Tells a client why its connection ends (best effort: its socket may be full).
async fn close_with<S>(sink: &mut Sink<S>, code: CloseCode, reason: &'static str)
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let frame = CloseFrame {
        code,
        reason: reason.into(),
    };
    // Closing is a courtesy: a client that is gone or stuck is dropped anyway.
    let _ = tokio::time::timeout(
        Duration::from_secs(1),
        sink.send(Message::Close(Some(frame))),
    )
    .await;
}

async fn run<S>(
    ws: WebSocketStream<S>,
    shared: &Sessions,
    stats: &ClientStats,
    frames: &mut broadcast::Receiver<rigcast_engine::tick::OutFrame>,
    events: &mut broadcast::Receiver<Event>,
) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let stall = shared.stalled_client_timeout;
    let (mut sink, mut stream) = ws.split();
    let hello = wire::hello(shared.rate_hz, &shared.feeds.subjects()).to_json();
    send(&mut sink, Message::text(hello), stall).await?;
    send_state(&mut sink, shared).await?;
    // `None` = all subjects.
    let mut subscribed: Option<HashSet<u32>> = None;
    // Frame version; version 1 until the client asks for another (`set_protocol`).
    let mut version = rigcast_protocol::PROTOCOL_VERSION;
    let mut pending_missed: u64 = 0;
    let mut shutdown = shared.feeds.shutdown.clone();
    // Answers of requests forwarded to other nodes (cluster mode).
    let (replies, mut forwarded) = mpsc::channel::<ServerMessage>(MAX_FORWARDS_IN_FLIGHT);
    loop {
        tokio::select! {
            biased;
            _ = shutdown.changed() => {
                close_with(&mut sink, CloseCode::Away, "server shutting down").await;
                return Ok(());
            }
            // Before frames, so a new skeleton arrives before frames that use it.
            event = events.recv() => {
                if !on_event(&mut sink, event, events, shared, stats).await? {
                    return Ok(());
                }
            }
            // `replies` lives as long as this loop, so this never yields `None`.
            Some(answer) = forwarded.recv() => send(&mut sink, Message::text(answer.to_json()), stall).await?,
            incoming = stream.next() => {
                let Some(incoming) = incoming else { return Ok(()) };
                let reply = match incoming {
                    Ok(Message::Text(text)) => {
                        let session = Session { access: stats.access, subscribed: &mut subscribed, version: &mut version, replies: &replies };
                        handle_text(text.as_str(), shared, session)
                    }
                    Ok(Message::Binary(b)) => Some(ServerMessage::error(
                        ErrorCode::BinaryNotAccepted,
                        format!("clients send JSON text messages only; got {} binary bytes", b.len()),
                    )),
                    Ok(Message::Close(_)) => return Ok(()),
                    // Pings are answered by tungstenite itself.
                    Ok(_) => None,
                    Err(tokio_tungstenite::tungstenite::Error::Capacity(_)) => {
                        close_with(&mut sink, CloseCode::Size, "frame over 64 KiB").await;
                        return Ok(());
                    }
                    // A violation is answered with its close code (RFC 6455 7.4.1) before
                    // the connection closes, so the client learns why.
                    Err(tokio_tungstenite::tungstenite::Error::Protocol(_)) => {
                        close_with(&mut sink, CloseCode::Protocol, "protocol violation").await;
                        return Ok(());
                    }
                    Err(tokio_tungstenite::tungstenite::Error::Utf8(_)) => {
                        close_with(&mut sink, CloseCode::Invalid, "text is not UTF-8").await;
                        return Ok(());
                    }
                    Err(_) => return Err(End::Transport),
                };
                if let Some(reply) = reply {
                    send(&mut sink, Message::text(reply.to_json()), stall).await?;
                }
            }
            received = frames.recv() => {
                // Every frame already queued goes out in one write: with several subjects a
                // tick produces several frames, and one syscall per client per tick is what
                // keeps fan-out cheap. The batch is bounded so control messages still get in.
                let mut next = Some(received);
                let mut batch = 0;
                // This write's frames (subject, capture, encoded), timed once it is written.
                let mut timed = [(0u32, 0u64, 0u64); MAX_FRAMES_PER_WRITE];
                let mut n_timed = 0;
                while let Some(received) = next.take() {
                    match received {
                        Ok(frame) => {
                            let wanted = subscribed.as_ref().is_none_or(|s| s.contains(&frame.subject));
                            let bytes = frame.version(version);
                            if wanted && !bytes.is_empty() {
                                let bytes = personalise(bytes, &mut pending_missed);
                                feed(&mut sink, Message::Binary(bytes), stall).await?;
                                stats.frames_sent.fetch_add(1, Ordering::Relaxed);
                                if let Some(t) = timed.get_mut(n_timed) {
                                    *t = (frame.subject, frame.capture_nanos, frame.send_nanos);
                                    n_timed += 1;
                                }
                            }
                        }
                        Err(RecvError::Lagged(n)) => {
                            pending_missed += n;
                            stats.missed_frames.fetch_add(n, Ordering::Relaxed);
                            shared.feeds.stats.dropped_frames.fetch_add(n, Ordering::Relaxed);
                            let text = ServerMessage::Lagged { missed: n }.to_json();
                            feed(&mut sink, Message::text(text), stall).await?;
                        }
                        Err(RecvError::Closed) => {
                            flush(&mut sink, stall).await?;
                            return Ok(());
                        }
                    }
                    batch += 1;
                    if batch < MAX_FRAMES_PER_WRITE {
                        next = next_queued(frames);
                    }
                }
                flush(&mut sink, stall).await?;
                record_written(shared, &timed[..n_timed]);
            }
        }
    }
}

/// Counts the frames of a write just taken by the client's socket into their subjects'
/// latency figures (each frame counts at its first write only; see `WireTimes`).
fn record_written(shared: &Sessions, frames: &[(u32, u64, u64)]) {
    let written = unix_nanos();
    for &(id, capture, encoded) in frames {
        if let Some(subject) = shared.subject(id) {
            if let Ok(mut wire) = subject.stats.wire.lock() {
                wire.sent(capture, encoded, written);
            }
        }
    }
}

/// What a message needs. Exhaustive on purpose: a new message type must choose.
fn required_access(msg: &ClientMessage) -> Access {
    match msg {
        // Choosing a frame version changes only what this client receives.
        ClientMessage::Subscribe { .. }
        | ClientMessage::Ping { .. }
        | ClientMessage::SetProtocol { .. } => Access::ReadOnly,
        ClientMessage::SetMapping { .. }
        | ClientMessage::Calibrate { .. }
        | ClientMessage::SetPerformer { .. } => Access::Control,
    }
}

/// A session's own settings that its messages change, and its reply queue.
struct Session<'a> {
    access: Access,
    subscribed: &'a mut Option<HashSet<u32>>,
    version: &'a mut u16,
    replies: &'a mpsc::Sender<ServerMessage>,
}

fn handle_text(text: &str, shared: &Sessions, session: Session<'_>) -> Option<ServerMessage> {
    let Session {
        access,
        subscribed,
        version,
        replies,
    } = session;
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
    if required_access(&msg) == Access::Control && access != Access::Control {
        return Some(ServerMessage::error(
            ErrorCode::Unauthorized,
            format!(
                "{} changes the server: connect with the control token \
                 (Authorization: Bearer TOKEN or ?token=TOKEN; `rigcast token show` prints it)",
                type_name(&msg)
            ),
        ));
    }
    if let Some(now) = forward_if_relayed(shared, &msg, replies) {
        return now;
    }
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
        } => subscribe(shared, ids, subscribed),
        change @ (ClientMessage::Calibrate { .. }
        | ClientMessage::SetPerformer { .. }
        | ClientMessage::SetMapping { .. }) => {
            Some(crate::changes::apply_change(&shared.changes, change))
        }
    }
}

/// In cluster mode, hands a change to another node's subject to that node: `Some(answer
/// now)` when it was taken (the owner's answer follows through `replies`) or refused here,
/// `None` when the subject is this node's own.
fn forward_if_relayed(
    shared: &Sessions,
    msg: &ClientMessage,
    replies: &mpsc::Sender<ServerMessage>,
) -> Option<Option<ServerMessage>> {
    let forwarder = shared.forwarder.as_ref()?;
    let id = crate::cluster::subject_of(msg)?;
    if !forwarder.is_relayed(id) {
        return None;
    }
    let Ok(permit) = replies.clone().try_reserve_owned() else {
        return Some(Some(ServerMessage::error(
            ErrorCode::Internal,
            format!("{MAX_FORWARDS_IN_FLIGHT} requests already wait for other nodes; retry"),
        )));
    };
    shared
        .feeds
        .stats
        .cluster_control_forwarded
        .fetch_add(1, Ordering::Relaxed);
    let answer = forwarder.clone().forward_change(id, msg.clone());
    tokio::spawn(async move {
        permit.send(answer.await);
    });
    Some(None)
}

/// `subscribe` to some subjects: all must exist, else nothing changes.
fn subscribe(
    shared: &Sessions,
    ids: Vec<u32>,
    subscribed: &mut Option<HashSet<u32>>,
) -> Option<ServerMessage> {
    let unknown: Vec<u32> = ids
        .iter()
        .copied()
        .filter(|id| shared.subject(*id).is_none())
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
