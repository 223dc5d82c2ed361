//! The requests a client sends: size and access checks, the answers, and the cluster-mode
//! forwarding of a change to the node that owns its subject.

use std::collections::HashSet;
use std::sync::atomic::Ordering;

use rigcast_engine::clock::unix_nanos;
use rigcast_protocol::control::{parse_client_message, ClientMessage, ErrorCode};
use rigcast_protocol::ServerMessage;
use tokio::sync::mpsc;

use crate::access::Access;
use crate::changes::type_name;
use crate::state::Sessions;

/// Largest client message the server interprets (control messages are small JSON). Larger
/// ones up to the transport limit are answered with `message_too_large`.
pub const MAX_CLIENT_MESSAGE_BYTES: usize = 32 * 1024;

/// Requests a session may have waiting for other nodes' answers at once.
pub(super) const MAX_FORWARDS_IN_FLIGHT: usize = 8;

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
pub(super) struct Session<'a> {
    pub(super) access: Access,
    pub(super) subscribed: &'a mut Option<HashSet<u32>>,
    pub(super) version: &'a mut u16,
    pub(super) replies: &'a mpsc::Sender<ServerMessage>,
}

pub(super) fn handle_text(
    text: &str,
    shared: &Sessions,
    session: Session<'_>,
) -> Option<ServerMessage> {
    let Session {
        access,
        subscribed,
        version,
        replies,
    } = session;
    let msg = match admitted(text, access) {
        Ok(m) => m,
        Err(refusal) => return Some(refusal),
    };
    if let Some(now) = forward_if_relayed(shared, &msg, replies) {
        return now;
    }
    match msg {
        ClientMessage::Ping { nonce } => Some(ServerMessage::Pong {
            nonce,
            server_nanos: unix_nanos(),
        }),
        ClientMessage::SetProtocol { version: wanted } => Some(set_protocol(wanted, version)),
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

/// The client's message if it may be taken: within the size limit, well formed, and of a kind
/// the session's `access` allows; else the error to answer.
fn admitted(text: &str, access: Access) -> Result<ClientMessage, ServerMessage> {
    if text.len() > MAX_CLIENT_MESSAGE_BYTES {
        return Err(ServerMessage::error(
            ErrorCode::MessageTooLarge,
            format!(
                "message of {} bytes exceeds the {MAX_CLIENT_MESSAGE_BYTES}-byte limit",
                text.len()
            ),
        ));
    }
    let msg = parse_client_message(text).map_err(|e| ServerMessage::error(e.code, e.message))?;
    if required_access(&msg) == Access::Control && access != Access::Control {
        return Err(ServerMessage::error(
            ErrorCode::Unauthorized,
            format!(
                "{} changes the server: connect with the control token \
                 (Authorization: Bearer TOKEN or ?token=TOKEN; `rigcast token show` prints it)",
                type_name(&msg)
            ),
        ));
    }
    Ok(msg)
}

/// Switches the session to protocol version `wanted` if this server speaks it.
fn set_protocol(wanted: u16, version: &mut u16) -> ServerMessage {
    if rigcast_protocol::PROTOCOL_VERSIONS.contains(&wanted) {
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
