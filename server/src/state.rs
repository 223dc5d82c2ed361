//! State shared by the listener, the client tasks and the status handler.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;

use rigcast_protocol::control::{ClientMessage, SubjectInfo};
use rigcast_protocol::ServerMessage;
use tokio::sync::{broadcast, watch};

use crate::access::AccessPolicy;
use crate::limits::{ConnectionLimiter, FdLimit};
use crate::recorder::RecorderHealth;
use crate::stats::{MappingShareCounts, Stats};
use rigcast_engine::events::Event;
use rigcast_engine::inbox::Inbox;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::OutFrame;

/// Shared server state (immutable apart from atomics and the stats' locks).
pub struct ServerState {
    /// Subjects in id order (id = index); grows when the cluster finds another node's.
    pub subject_list: Arc<rigcast_engine::subject_list::SubjectList>,
    /// Frame fan-out; client tasks call `subscribe`.
    pub frames: broadcast::Sender<OutFrame>,
    /// What every client is told about (`mapping`, `skeleton`, `subjects_changed`,
    /// `source_status`, `footplants`, faults), typed; `wire` makes them messages.
    pub events: broadcast::Sender<Event>,
    /// Counters.
    pub stats: Arc<Stats>,
    /// Output rate.
    pub rate_hz: f64,
    /// Client id allocator.
    pub next_client_id: AtomicU64,
    /// Becomes `true` on shutdown.
    pub shutdown: watch::Receiver<bool>,
    /// Where requests for the engine are left (`set_mapping`, `set_performer`).
    pub inbox: Inbox,
    /// Origin/Host/token rules of the listener.
    pub policy: AccessPolicy,
    /// The connection cap.
    pub connections: Arc<ConnectionLimiter>,
    /// The open-file limit at start.
    pub fd_limit: Option<FdLimit>,
    /// How long a client's socket may accept nothing before it is dropped.
    pub stalled_client_timeout: std::time::Duration,
    /// The recording's health, if recording (its errors show in the status).
    pub recorder: Option<Arc<RecorderHealth>>,
    /// Cluster mode: this node's site and counters, for the status.
    pub cluster: Option<ClusterView>,
    /// Cluster mode: where changes to relayed subjects go.
    pub forwarder: Option<Arc<dyn ChangeForwarder>>,
}

/// What a task that carries the server's output elsewhere sees of it, and nothing more: the
/// subjects, the frame and event broadcasts, the shutdown signal and the counters (the
/// cluster's publisher and relays take this instead of the whole [`ServerState`]: no access
/// policy, connection cap or client bookkeeping).
#[derive(Clone)]
pub struct Feeds {
    /// Subjects in id order (id = index).
    pub subject_list: Arc<rigcast_engine::subject_list::SubjectList>,
    /// Frame fan-out.
    pub frames: broadcast::Sender<OutFrame>,
    /// What every client is told about, typed.
    pub events: broadcast::Sender<Event>,
    /// Becomes `true` on shutdown.
    pub shutdown: watch::Receiver<bool>,
    /// Counters.
    pub stats: Arc<Stats>,
}

impl Feeds {
    /// The subjects now.
    pub fn subjects(&self) -> Arc<Vec<Arc<Subject>>> {
        self.subject_list.snapshot()
    }
}

/// What the requests that change the server (`changes`) see: the subjects, the events to tell
/// clients of a change and the engine's inbox (for the requests it passes to the mapper).
#[derive(Clone)]
pub struct Changes {
    /// Subjects in id order (id = index).
    pub subject_list: Arc<rigcast_engine::subject_list::SubjectList>,
    /// What every client is told about, typed.
    pub events: broadcast::Sender<Event>,
    /// Where requests for the engine are left.
    pub inbox: Inbox,
}

impl Changes {
    /// The subjects now.
    pub fn subjects(&self) -> Arc<Vec<Arc<Subject>>> {
        self.subject_list.snapshot()
    }

    /// A subject by id.
    pub fn subject(&self, id: u32) -> Option<Arc<Subject>> {
        self.subject_list.get(id)
    }
}

/// What a WebSocket session sees: the feeds it streams from, the requests that change the
/// server, where changes to relayed subjects go, the output rate it announces and how long its
/// socket may accept nothing (no access policy, connection cap or listener: the listener
/// checks those before a session starts, and gives it its client id).
#[derive(Clone)]
pub struct Sessions {
    /// The subjects, broadcasts, shutdown signal and counters.
    pub feeds: Feeds,
    /// The requests that change the server.
    pub changes: Changes,
    /// Cluster mode: where changes to relayed subjects go.
    pub forwarder: Option<Arc<dyn ChangeForwarder>>,
    /// Output rate.
    pub rate_hz: f64,
    /// How long a client's socket may accept nothing before it is dropped.
    pub stalled_client_timeout: std::time::Duration,
}

impl Sessions {
    /// A subject by id.
    pub fn subject(&self, id: u32) -> Option<Arc<Subject>> {
        self.feeds.subject_list.get(id)
    }

    /// The subjects as listed in `hello` and `subjects_changed`.
    pub fn subject_infos(&self) -> Vec<SubjectInfo> {
        self.feeds.subjects().iter().map(|s| s.info()).collect()
    }
}

/// What the cluster's control service sees: the requests it carries out for other nodes, the
/// token their requests must prove, the shutdown signal and the counters (no frames, access
/// policy, connection cap or client bookkeeping).
#[derive(Clone)]
pub struct ControlService {
    /// The requests that change the server.
    pub changes: Changes,
    /// The deployment's control token.
    pub token: crate::token::ControlToken,
    /// Becomes `true` on shutdown.
    pub shutdown: watch::Receiver<bool>,
    /// Counters.
    pub stats: Arc<Stats>,
}

/// What the cluster's bucket watch sees: the feeds (to relay a subject it finds and tell
/// clients of it) and the engine's inbox (a found subject's live thread asks for a re-map when
/// its skeleton changes).
#[derive(Clone)]
pub struct Discovery {
    /// The subjects, broadcasts, shutdown signal and counters.
    pub feeds: Feeds,
    /// Where requests for the engine are left.
    pub inbox: Inbox,
}

/// Cluster mode as the status shows it (the connection itself stays in `cluster`).
pub struct ClusterView {
    /// This node's name in the deployment.
    pub site: String,
    /// How often the shared mapping cache was used.
    pub mapping_counts: Arc<MappingShareCounts>,
}

impl ServerState {
    /// The part of the state a task carrying the output elsewhere sees.
    pub fn feeds(&self) -> Feeds {
        Feeds {
            subject_list: self.subject_list.clone(),
            frames: self.frames.clone(),
            events: self.events.clone(),
            shutdown: self.shutdown.clone(),
            stats: self.stats.clone(),
        }
    }

    /// The part of the state a WebSocket session sees.
    pub fn sessions(&self) -> Sessions {
        Sessions {
            feeds: self.feeds(),
            changes: self.changes(),
            forwarder: self.forwarder.clone(),
            rate_hz: self.rate_hz,
            stalled_client_timeout: self.stalled_client_timeout,
        }
    }

    /// The part of the state the cluster's control service sees.
    pub fn control_service(&self) -> ControlService {
        ControlService {
            changes: self.changes(),
            token: self.policy.token().clone(),
            shutdown: self.shutdown.clone(),
            stats: self.stats.clone(),
        }
    }

    /// The part of the state the cluster's bucket watch sees.
    pub fn discovery(&self) -> Discovery {
        Discovery {
            feeds: self.feeds(),
            inbox: self.inbox.clone(),
        }
    }

    /// The part of the state the requests that change the server see.
    pub fn changes(&self) -> Changes {
        Changes {
            subject_list: self.subject_list.clone(),
            events: self.events.clone(),
            inbox: self.inbox.clone(),
        }
    }

    /// The subjects now.
    pub fn subjects(&self) -> Arc<Vec<Arc<Subject>>> {
        self.subject_list.snapshot()
    }

    /// A subject by id.
    pub fn subject(&self, id: u32) -> Option<Arc<Subject>> {
        self.subject_list.get(id)
    }

    /// The subjects as listed in `hello`.
    pub fn subject_infos(&self) -> Vec<SubjectInfo> {
        self.subjects().iter().map(|s| s.info()).collect()
    }
}

/// Where changes to subjects relayed from other nodes go (cluster mode: `cluster::Forwarder`).
/// A trait so that the state and the client sessions need no NATS.
pub trait ChangeForwarder: Send + Sync {
    /// Whether local subject `id` is relayed from another node.
    fn is_relayed(&self, id: u32) -> bool;

    /// Sends `msg` about relayed subject `id` to its owner; resolves to the owner's answer.
    fn forward_change(
        self: Arc<Self>,
        id: u32,
        msg: ClientMessage,
    ) -> Pin<Box<dyn Future<Output = ServerMessage> + Send>>;
}
