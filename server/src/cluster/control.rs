//! Control across nodes: a request that changes a relayed subject (`set_mapping`,
//! `set_performer`, `calibrate`) is carried out by the node that owns the subject, because its
//! performer (or device) runs there.
//!
//! ```text
//!  client ─▶ node C (token checked, subject is `mannequin@b`)
//!              └─ NATS request {ns}.control.b: {body, proof} ─▶ node B: proof checked with
//!                                                               B's token, request applied
//!  client ◀─ C: reply, subject id made C's ◀──────────────── reply (ack or error)
//! ```
//!
//! The control token is per deployment: every node holds the same token file. It never
//! travels: a forwarded request carries an HMAC-SHA256 of its body keyed with the forwarding
//! node's token, and the owning node checks it with its own, so a node (or anything else on
//! NATS) without the deployment's token is refused there too. The body names both sites and
//! carries its send time; the owner refuses a body older than [`CLOCK_WINDOW`] or already
//! seen, so a recorded request cannot be played again.

use std::collections::{HashMap, VecDeque};
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::Ordering;
use std::sync::{Arc, RwLock};
use std::time::Duration;

use futures_util::StreamExt;
use rigcast_protocol::control::{ClientMessage, ErrorCode};
use rigcast_protocol::ServerMessage;
use ring::hmac;
use serde::{Deserialize, Serialize};

use crate::state::ChangeForwarder;
use crate::state::ControlService;
use crate::token::ControlToken;
use rigcast_engine::clock::unix_nanos;

/// Longest a forwarding node waits for the owner's answer.
pub const CONTROL_TIMEOUT: Duration = Duration::from_secs(2);
/// How far a body's send time may be from the owner's clock (clocks of a deployment's
/// machines are assumed synchronised to well within this).
pub const CLOCK_WINDOW: Duration = Duration::from_secs(30);
/// Bodies remembered against replays (a deployment sends a few control requests a second).
const SEEN_MAX: usize = 1024;

/// Where a relayed subject lives: the owning site and the subject's name there.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Origin {
    /// The owning node.
    pub site: String,
    /// The subject's name on it.
    pub name: String,
}

/// What a forwarded request says (signed as the exact JSON text sent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Body {
    from: String,
    to: String,
    name: String,
    message: ClientMessage,
    sent_nanos: u64,
}

/// A forwarded request on the wire: the body's JSON and its proof (hex HMAC-SHA256).
#[derive(Debug, Serialize, Deserialize)]
struct Envelope {
    body: String,
    proof: String,
}

fn key(token: &ControlToken) -> hmac::Key {
    hmac::Key::new(hmac::HMAC_SHA256, token.reveal().as_bytes())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(text: &str) -> Option<Vec<u8>> {
    if text.len() & 1 == 1 {
        return None;
    }
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(text.get(i..i + 2)?, 16).ok())
        .collect()
}

/// The wire form of `body`, signed with `token`.
fn seal(token: &ControlToken, body: &Body) -> Vec<u8> {
    let text = serde_json::to_string(body).unwrap_or_default();
    let proof = hex(hmac::sign(&key(token), text.as_bytes()).as_ref());
    serde_json::to_vec(&Envelope { body: text, proof }).unwrap_or_default()
}

/// Why the owning node refused a forwarded request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Refusal {
    /// Not an envelope, or its body is not a request.
    Malformed,
    /// Signed with another token (or not at all).
    WrongToken,
    /// Addressed to another site.
    NotForUs,
    /// Sent outside the clock window.
    Stale,
    /// This exact body was seen before.
    Replayed,
}

impl Refusal {
    fn reply(self, site: &str) -> ServerMessage {
        let (code, text) = match self {
            Refusal::Malformed => (ErrorCode::InvalidFields, "not a rigcast control request"),
            Refusal::WrongToken => (
                ErrorCode::Unauthorized,
                "the forwarding node does not hold this deployment's control token",
            ),
            Refusal::NotForUs => (ErrorCode::InvalidFields, "addressed to another node"),
            Refusal::Stale => (
                ErrorCode::Unauthorized,
                "sent too long ago (or the nodes' clocks disagree by over 30 s)",
            ),
            Refusal::Replayed => (ErrorCode::Unauthorized, "this request was already served"),
        };
        ServerMessage::error(code, format!("node {site} refused the request: {text}"))
    }
}

/// The owner's check of incoming envelopes: proof, address, freshness, replays.
struct Checker {
    key: hmac::Key,
    site: String,
    seen: VecDeque<(String, u64)>,
}

impl Checker {
    fn new(token: &ControlToken, site: &str) -> Checker {
        Checker {
            key: key(token),
            site: site.to_string(),
            seen: VecDeque::new(),
        }
    }

    fn open(&mut self, bytes: &[u8], now_nanos: u64) -> Result<Body, Refusal> {
        let envelope: Envelope = serde_json::from_slice(bytes).map_err(|_| Refusal::Malformed)?;
        let proof = unhex(&envelope.proof).ok_or(Refusal::WrongToken)?;
        hmac::verify(&self.key, envelope.body.as_bytes(), &proof)
            .map_err(|_| Refusal::WrongToken)?;
        let body: Body = serde_json::from_str(&envelope.body).map_err(|_| Refusal::Malformed)?;
        if body.to != self.site {
            return Err(Refusal::NotForUs);
        }
        if now_nanos.abs_diff(body.sent_nanos) > CLOCK_WINDOW.as_nanos() as u64 {
            return Err(Refusal::Stale);
        }
        let id = (body.from.clone(), body.sent_nanos);
        if self.seen.contains(&id) {
            return Err(Refusal::Replayed);
        }
        if self.seen.len() >= SEEN_MAX {
            self.seen.pop_front();
        }
        self.seen.push_back(id);
        Ok(body)
    }
}

/// The one subject a request that changes the server is about.
pub fn subject_of(msg: &ClientMessage) -> Option<u32> {
    match msg {
        ClientMessage::SetMapping { subject, .. }
        | ClientMessage::SetPerformer { subject, .. }
        | ClientMessage::Calibrate { subject, .. } => Some(*subject),
        ClientMessage::Subscribe { .. }
        | ClientMessage::Ping { .. }
        | ClientMessage::SetProtocol { .. } => None,
    }
}

/// `msg` about subject `id` instead (ids are per node).
fn readdressed(mut msg: ClientMessage, id: u32) -> ClientMessage {
    match &mut msg {
        ClientMessage::SetMapping { subject, .. }
        | ClientMessage::SetPerformer { subject, .. }
        | ClientMessage::Calibrate { subject, .. } => *subject = id,
        ClientMessage::Subscribe { .. }
        | ClientMessage::Ping { .. }
        | ClientMessage::SetProtocol { .. } => {}
    }
    msg
}

/// The forwarding side: which local subjects are relayed from where, and the NATS client
/// that carries their control requests.
pub struct Forwarder {
    client: async_nats::Client,
    namespace: String,
    site: String,
    token: ControlToken,
    origins: RwLock<HashMap<u32, Origin>>,
}

impl Forwarder {
    /// A forwarder for node `site` of deployment `namespace`, signing with `token`.
    pub fn new(
        client: async_nats::Client,
        namespace: &str,
        site: &str,
        token: ControlToken,
    ) -> Forwarder {
        Forwarder {
            client,
            namespace: namespace.to_string(),
            site: site.to_string(),
            token,
            origins: RwLock::new(HashMap::new()),
        }
    }

    /// Records that local subject `id` is relayed from `origin`.
    pub fn add(&self, id: u32, origin: Origin) {
        if let Ok(mut o) = self.origins.write() {
            o.insert(id, origin);
        }
    }

    /// Where local subject `id` comes from, when it is relayed.
    pub fn origin(&self, id: u32) -> Option<Origin> {
        self.origins.read().ok()?.get(&id).cloned()
    }

    /// Sends `msg` (about local subject `id`, relayed from `origin`) to its owner and returns
    /// the owner's answer, its subject id made this node's.
    pub async fn forward(&self, id: u32, origin: &Origin, msg: ClientMessage) -> ServerMessage {
        let body = Body {
            from: self.site.clone(),
            to: origin.site.clone(),
            name: origin.name.clone(),
            message: msg,
            sent_nanos: unix_nanos(),
        };
        let subject = control_subject(&self.namespace, &origin.site);
        let request = self
            .client
            .request(subject, seal(&self.token, &body).into());
        let reply = match tokio::time::timeout(CONTROL_TIMEOUT, request).await {
            Ok(Ok(reply)) => reply,
            Ok(Err(e)) if e.kind() == async_nats::RequestErrorKind::NoResponders => {
                return unreachable_owner(&origin.site, "is not connected to the cluster");
            }
            Ok(Err(_)) | Err(_) => {
                return unreachable_owner(&origin.site, "did not answer within 2 s");
            }
        };
        match serde_json::from_slice::<ServerMessage>(&reply.payload) {
            Ok(ServerMessage::Ack { request, .. }) => ServerMessage::Ack {
                request,
                subject: id,
            },
            // The owner's ids in its text are its own: say whose they are.
            Ok(ServerMessage::Error { code, message, .. }) if !message.starts_with("node ") => {
                ServerMessage::error(code, format!("node {}: {message}", origin.site))
            }
            Ok(other @ ServerMessage::Error { .. }) => other,
            _ => ServerMessage::error(
                ErrorCode::Internal,
                format!(
                    "node {} answered something else than ack or error",
                    origin.site
                ),
            ),
        }
    }
}

impl ChangeForwarder for Forwarder {
    fn is_relayed(&self, id: u32) -> bool {
        self.origin(id).is_some()
    }

    fn forward_change(
        self: Arc<Self>,
        id: u32,
        msg: ClientMessage,
    ) -> Pin<Box<dyn Future<Output = ServerMessage> + Send>> {
        Box::pin(async move {
            match self.origin(id) {
                Some(origin) => self.forward(id, &origin, msg).await,
                None => ServerMessage::error(
                    ErrorCode::Internal,
                    format!("subject {id} is not relayed from another node"),
                ),
            }
        })
    }
}

fn unreachable_owner(site: &str, why: &str) -> ServerMessage {
    ServerMessage::error(
        ErrorCode::Internal,
        format!("node {site}, which owns this subject, {why}; retry"),
    )
}

/// The NATS subject on which node `site` takes control requests.
pub fn control_subject(namespace: &str, site: &str) -> String {
    format!("{namespace}.control.{site}")
}

/// Serves the control requests other nodes forward to this one until shutdown.
pub async fn run_control_service(
    client: async_nats::Client,
    namespace: String,
    site: String,
    handle: ControlService,
) {
    let subject = control_subject(&namespace, &site);
    let mut sub = match client.subscribe(subject.clone()).await {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cluster: cannot take control requests on {subject}: {e}");
            return;
        }
    };
    let mut checker = Checker::new(&handle.token, &site);
    let mut shutdown = handle.shutdown.clone();
    loop {
        let msg = tokio::select! {
            biased;
            _ = shutdown.changed() => break,
            msg = sub.next() => match msg {
                Some(m) => m,
                None => break,
            },
        };
        let Some(reply_to) = msg.reply else { continue };
        let answer = serve(&mut checker, &msg.payload, &handle);
        // The asker may have given up (timeout); nothing more to do then.
        let _ = client
            .publish(reply_to, answer.to_json().into_bytes().into())
            .await;
    }
}

/// The answer to one forwarded request.
fn serve(checker: &mut Checker, payload: &[u8], handle: &ControlService) -> ServerMessage {
    let body = match checker.open(payload, unix_nanos()) {
        Ok(b) => b,
        Err(refusal) => {
            handle
                .stats
                .cluster_control_refused
                .fetch_add(1, Ordering::Relaxed);
            return refusal.reply(&checker.site);
        }
    };
    handle
        .stats
        .cluster_control_served
        .fetch_add(1, Ordering::Relaxed);
    let subjects = handle.changes.subjects();
    let own = (subjects.iter()).find(|s| !s.is_relayed() && s.info().name == body.name);
    let Some(own) = own else {
        return ServerMessage::error(
            ErrorCode::UnknownSubject,
            format!("node {} has no subject {:?}", checker.site, body.name),
        );
    };
    crate::changes::apply_change(&handle.changes, readdressed(body.message, own.id))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn token(t: &str) -> ControlToken {
        ControlToken::from_text(t).unwrap()
    }

    fn body(sent_nanos: u64) -> Body {
        Body {
            from: "c".into(),
            to: "b".into(),
            name: "mannequin".into(),
            message: ClientMessage::SetPerformer {
                subject: 4,
                foot_lock: Some(false),
            },
            sent_nanos,
        }
    }

    const NOW: u64 = 1_700_000_000_000_000_000;

    #[test]
    fn the_owner_accepts_only_its_deployment_s_token_once_and_fresh() {
        let shared = token("deployment-token-0123456789");
        let mut owner = Checker::new(&shared, "b");
        let sealed = seal(&shared, &body(NOW));
        assert_eq!(owner.open(&sealed, NOW + 1_000), Ok(body(NOW)));
        // The same request again is a replay.
        assert_eq!(owner.open(&sealed, NOW + 2_000), Err(Refusal::Replayed));
        // Another token's proof fails.
        let other = seal(&token("some-other-token-0123456789"), &body(NOW + 5));
        assert_eq!(owner.open(&other, NOW + 6), Err(Refusal::WrongToken));
        // Too old, or addressed elsewhere.
        let old = seal(&shared, &body(NOW - 31_000_000_000));
        assert_eq!(owner.open(&old, NOW), Err(Refusal::Stale));
        let mut elsewhere = body(NOW + 7);
        elsewhere.to = "a".into();
        assert_eq!(
            owner.open(&seal(&shared, &elsewhere), NOW + 8),
            Err(Refusal::NotForUs)
        );
    }

    #[test]
    fn a_tampered_body_or_garbage_is_refused() {
        let shared = token("deployment-token-0123456789");
        let mut owner = Checker::new(&shared, "b");
        let sealed = seal(&shared, &body(NOW));
        let mut env: Envelope = serde_json::from_slice(&sealed).unwrap();
        env.body = env.body.replace("mannequin", "robot");
        let tampered = serde_json::to_vec(&env).unwrap();
        assert_eq!(owner.open(&tampered, NOW), Err(Refusal::WrongToken));
        assert_eq!(owner.open(b"{}", NOW), Err(Refusal::Malformed));
        assert_eq!(owner.open(b"\xff", NOW), Err(Refusal::Malformed));
        env.proof = "zz".into();
        let bad_hex = serde_json::to_vec(&env).unwrap();
        assert_eq!(owner.open(&bad_hex, NOW), Err(Refusal::WrongToken));
    }

    #[test]
    fn requests_are_readdressed_to_the_owner_s_ids() {
        let m = readdressed(body(NOW).message, 9);
        assert_eq!(subject_of(&m), Some(9));
        assert_eq!(subject_of(&ClientMessage::Ping { nonce: 1 }), None);
    }
}
