//! State shared by the listener, the client tasks and the status handler.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;

use rigcast_protocol::control::{ClientMessage, SubjectInfo};
use rigcast_protocol::ServerMessage;
use tokio::sync::{broadcast, mpsc, watch};

use crate::access::AccessPolicy;
use crate::engine::{EngineCommand, OutFrame, Subject};
use crate::events::Event;
use crate::limits::{ConnectionLimiter, FdLimit};
use crate::recorder::RecorderHealth;
use crate::stats::{MappingShareCounts, Stats};

/// Shared server state (immutable apart from atomics and the stats' locks).
pub struct ServerState {
    /// Subjects in id order (id = index); grows when the cluster finds another node's.
    pub subject_list: Arc<crate::subject_list::SubjectList>,
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
    /// Requests to the engine.
    pub commands: mpsc::Sender<EngineCommand>,
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
    pub subject_list: Arc<crate::subject_list::SubjectList>,
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
/// clients of a change and the mapper's command queue.
#[derive(Clone)]
pub struct Changes {
    /// Subjects in id order (id = index).
    pub subject_list: Arc<crate::subject_list::SubjectList>,
    /// What every client is told about, typed.
    pub events: broadcast::Sender<Event>,
    /// Requests to the mapper.
    pub commands: mpsc::Sender<EngineCommand>,
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

    /// The part of the state the requests that change the server see.
    pub fn changes(&self) -> Changes {
        Changes {
            subject_list: self.subject_list.clone(),
            events: self.events.clone(),
            commands: self.commands.clone(),
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
