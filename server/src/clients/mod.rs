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

mod requests;
mod socket;

use std::collections::HashSet;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use futures_util::StreamExt;
use rigcast_engine::clock::unix_nanos;
use rigcast_engine::events::Event;
use rigcast_engine::tick::OutFrame;
use rigcast_protocol::control::ErrorCode;
use rigcast_protocol::frame::set_missed_frames;
use rigcast_protocol::ServerMessage;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::sync::broadcast::error::{RecvError, TryRecvError};
use tokio::sync::{broadcast, mpsc};
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::{self, Bytes, Message};
use tokio_tungstenite::WebSocketStream;

use crate::access::Access;
use crate::state::Sessions;
use crate::stats::ClientStats;
use crate::wire;
use requests::{handle_text, Session, MAX_FORWARDS_IN_FLIGHT};
use socket::{close_reason, close_with, feed, flush, send, End, Sink};

pub use requests::MAX_CLIENT_MESSAGE_BYTES;
pub use socket::MAX_TRANSPORT_MESSAGE_BYTES;

/// Frames sent in one write at most (a tick makes one per subject).
const MAX_FRAMES_PER_WRITE: usize = 32;

/// What shapes the frames one client receives: its subscription, its frame version and the
/// frames it missed since its last one.
struct View {
    /// `None` = all subjects.
    subscribed: Option<HashSet<u32>>,
    /// Version 1 until the client asks for another (`set_protocol`).
    version: u16,
    pending_missed: u64,
}

/// The next frame already queued for this client, if any (never waits).
fn next_queued(frames: &mut broadcast::Receiver<OutFrame>) -> Option<Result<OutFrame, RecvError>> {
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

/// The session: greets the client, then serves whichever comes first of shutdown, a control
/// event, a forwarded answer, the client's message and the next frames, until one ends it.
async fn run<S>(
    ws: WebSocketStream<S>,
    shared: &Sessions,
    stats: &ClientStats,
    frames: &mut broadcast::Receiver<OutFrame>,
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
    let mut view = View {
        subscribed: None,
        version: rigcast_protocol::PROTOCOL_VERSION,
        pending_missed: 0,
    };
    let mut shutdown = shared.feeds.shutdown.clone();
    // Answers of requests forwarded to other nodes (cluster mode).
    let (replies, mut forwarded) = mpsc::channel::<ServerMessage>(MAX_FORWARDS_IN_FLIGHT);
    loop {
        let go_on = tokio::select! {
            biased;
            _ = shutdown.changed() => {
                close_with(&mut sink, CloseCode::Away, "server shutting down").await;
                false
            }
            // Before frames, so a new skeleton arrives before frames that use it.
            event = events.recv() => on_event(&mut sink, event, events, shared, stats).await?,
            // `replies` lives as long as this loop, so this never yields `None`.
            Some(answer) = forwarded.recv() => {
                send(&mut sink, Message::text(answer.to_json()), stall).await?;
                true
            }
            incoming = stream.next() => match incoming {
                Some(incoming) => {
                    let session = Session {
                        access: stats.access,
                        subscribed: &mut view.subscribed,
                        version: &mut view.version,
                        replies: &replies,
                    };
                    on_incoming(&mut sink, incoming, shared, session).await?
                }
                None => false,
            },
            received = frames.recv() => send_frames(&mut sink, received, frames, &mut view, shared, stats).await?,
        };
        if !go_on {
            return Ok(());
        }
    }
}

/// Answers one message from the client; `false` once the connection is to end.
async fn on_incoming<S>(
    sink: &mut Sink<S>,
    incoming: Result<Message, tungstenite::Error>,
    shared: &Sessions,
    session: Session<'_>,
) -> Result<bool, End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let reply = match incoming {
        Ok(Message::Text(text)) => handle_text(text.as_str(), shared, session),
        Ok(Message::Binary(b)) => Some(ServerMessage::error(
            ErrorCode::BinaryNotAccepted,
            format!(
                "clients send JSON text messages only; got {} binary bytes",
                b.len()
            ),
        )),
        Ok(Message::Close(_)) => return Ok(false),
        // Pings are answered by tungstenite itself.
        Ok(_) => None,
        Err(error) => {
            let (code, reason) = close_reason(&error).ok_or(End::Transport)?;
            close_with(sink, code, reason).await;
            return Ok(false);
        }
    };
    if let Some(reply) = reply {
        send(
            sink,
            Message::text(reply.to_json()),
            shared.stalled_client_timeout,
        )
        .await?;
    }
    Ok(true)
}

/// Sends a frame and every frame already queued behind it in one write; `false` once the
/// frame queue is closed (shutdown).
///
/// One write per tick: with several subjects a tick produces several frames, and one
/// syscall per client per tick is what keeps fan-out cheap. The batch is bounded so control
/// messages still get in.
async fn send_frames<S>(
    sink: &mut Sink<S>,
    received: Result<OutFrame, RecvError>,
    frames: &mut broadcast::Receiver<OutFrame>,
    view: &mut View,
    shared: &Sessions,
    stats: &ClientStats,
) -> Result<bool, End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let stall = shared.stalled_client_timeout;
    let mut next = Some(received);
    let mut batch = 0;
    // This write's frames (subject, capture, encoded), timed once it is written.
    let mut timed = [(0u32, 0u64, 0u64); MAX_FRAMES_PER_WRITE];
    let mut n_timed = 0;
    while let Some(received) = next.take() {
        match received {
            Ok(frame) => {
                if feed_frame(sink, &frame, view, stall).await? {
                    stats.frames_sent.fetch_add(1, Ordering::Relaxed);
                    if let Some(t) = timed.get_mut(n_timed) {
                        *t = (frame.subject, frame.capture_nanos, frame.send_nanos);
                        n_timed += 1;
                    }
                }
            }
            Err(RecvError::Lagged(n)) => {
                view.pending_missed += n;
                stats.missed_frames.fetch_add(n, Ordering::Relaxed);
                shared
                    .feeds
                    .stats
                    .dropped_frames
                    .fetch_add(n, Ordering::Relaxed);
                let text = ServerMessage::Lagged { missed: n }.to_json();
                feed(sink, Message::text(text), stall).await?;
            }
            Err(RecvError::Closed) => {
                flush(sink, stall).await?;
                return Ok(false);
            }
        }
        batch += 1;
        if batch < MAX_FRAMES_PER_WRITE {
            next = next_queued(frames);
        }
    }
    flush(sink, stall).await?;
    record_written(shared, &timed[..n_timed]);
    Ok(true)
}

/// Queues one frame if the client wants it, in its version; `true` when queued.
async fn feed_frame<S>(
    sink: &mut Sink<S>,
    frame: &OutFrame,
    view: &mut View,
    stall: std::time::Duration,
) -> Result<bool, End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let wanted = view
        .subscribed
        .as_ref()
        .is_none_or(|s| s.contains(&frame.subject));
    let bytes = frame.version(view.version);
    if !wanted || bytes.is_empty() {
        return Ok(false);
    }
    let bytes = personalise(bytes, &mut view.pending_missed);
    feed(sink, Message::Binary(bytes), stall).await?;
    Ok(true)
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
