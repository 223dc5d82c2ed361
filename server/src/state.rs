//! State shared by the listener, the client tasks and the status handler.

use std::sync::atomic::AtomicU64;
use std::sync::Arc;

use rigcast_protocol::control::SubjectInfo;
use rigcast_protocol::{ServerMessage, PROTOCOL_VERSION};
use tokio::sync::{broadcast, mpsc, watch};

use crate::access::AccessPolicy;
use crate::engine::{EngineCommand, OutFrame, Subject};
use crate::limits::{ConnectionLimiter, FdLimit};
use crate::recorder::RecorderHealth;
use crate::stats::Stats;

/// Shared server state (immutable apart from atomics and the stats' locks).
pub struct ServerState {
    /// Subjects in id order (id = index); grows when the cluster finds another node's.
    pub subject_list: Arc<crate::subject_list::SubjectList>,
    /// Frame fan-out; client tasks call `subscribe`.
    pub frames: broadcast::Sender<OutFrame>,
    /// Control messages for every client (`mapping`, `skeleton`, `subjects_changed`,
    /// `source_status`), as JSON text.
    pub events: broadcast::Sender<String>,
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
    /// Cluster mode: the connection (its settings and counters, for the status).
    pub cluster: Option<Arc<crate::cluster::Cluster>>,
    /// Cluster mode: where relayed subjects' control requests go.
    pub forwarder: Option<Arc<crate::cluster::Forwarder>>,
}

impl ServerState {
    /// The subjects now.
    pub fn subjects(&self) -> Arc<Vec<Arc<Subject>>> {
        self.subject_list.snapshot()
    }

    /// A subject by id.
    pub fn subject(&self, id: u32) -> Option<Arc<Subject>> {
        self.subjects()
            .get(id as usize)
            .filter(|s| s.id == id)
            .cloned()
    }

    /// The subjects as listed in `hello`.
    pub fn subject_infos(&self) -> Vec<SubjectInfo> {
        self.subjects().iter().map(|s| s.info()).collect()
    }

    /// The `hello` message.
    pub fn hello_json(&self) -> String {
        ServerMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            protocol_versions: rigcast_protocol::PROTOCOL_VERSIONS.to_vec(),
            server_version: env!("CARGO_PKG_VERSION").to_string(),
            tick_hz: self.rate_hz,
            subjects: self.subject_infos(),
        }
        .to_json()
    }
}
