//! The client's socket as this server writes it: every write bounded by the stall timeout,
//! and the close frames that tell a client why its connection ends.

use std::time::Duration;

use futures_util::stream::SplitSink;
use futures_util::SinkExt;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio_tungstenite::tungstenite::protocol::frame::coding::CloseCode;
use tokio_tungstenite::tungstenite::protocol::CloseFrame;
use tokio_tungstenite::tungstenite::{Error, Message};
use tokio_tungstenite::WebSocketStream;

/// Transport limit given to tungstenite, per frame and per message: beyond it the connection
/// is closed with 1009. Small, so that the connection cap times this stays modest memory.
pub const MAX_TRANSPORT_MESSAGE_BYTES: usize = 64 * 1024;

/// Why a session ended early (a clean end is `Ok`).
pub(super) enum End {
    /// The client's socket accepted nothing for the stall timeout.
    Stalled,
    /// The WebSocket layer failed (protocol error, reset): nothing more to tell the client.
    Transport,
}

pub(super) type Sink<S> = SplitSink<WebSocketStream<S>, Message>;

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
pub(super) async fn send<S>(sink: &mut Sink<S>, msg: Message, stall: Duration) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    within(stall, sink.send(msg)).await
}

/// Queues one message without writing it yet (see [`flush`]).
pub(super) async fn feed<S>(sink: &mut Sink<S>, msg: Message, stall: Duration) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    within(stall, sink.feed(msg)).await
}

/// Writes what [`feed`] queued.
pub(super) async fn flush<S>(sink: &mut Sink<S>, stall: Duration) -> Result<(), End>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    within(stall, sink.flush()).await
}

/// Tells a client why its connection ends (best effort: its socket may be full).
pub(super) async fn close_with<S>(sink: &mut Sink<S>, code: CloseCode, reason: &'static str)
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

/// The close code and reason for a read error the client caused, `None` for a transport
/// failure (nothing more can be told to the client then).
pub(super) fn close_reason(error: &Error) -> Option<(CloseCode, &'static str)> {
    match error {
        Error::Capacity(_) => Some((CloseCode::Size, "frame over 64 KiB")),
        // A violation is answered with its close code (RFC 6455 7.4.1) before the
        // connection closes, so the client learns why.
        Error::Protocol(_) => Some((CloseCode::Protocol, "protocol violation")),
        Error::Utf8(_) => Some((CloseCode::Invalid, "text is not UTF-8")),
        _ => None,
    }
}
