//! Server start in three steps, each its own module:
//!
//! ```text
//!  ServerConfig ─▶ load (sources, characters, mapping files, token: blocking IO)
//!               ─▶ assemble (subjects, performer plans + first mappings, VMC receivers)
//!               ─▶ spawn (recording, listener; every task and thread under a Supervisor)
//! ```
//!
//! Adding a source kind touches `load` only (one arm of `load_source`) plus its own module.

pub(crate) mod assemble;
pub(crate) mod load;
pub mod spawn;

pub use spawn::Supervisor;

use std::net::SocketAddr;
use std::sync::Arc;

use crate::config::ServerConfig;
use crate::state::ServerState;
use crate::token::{self, ControlToken};

/// Loads the sources and characters, binds the listener and starts the engine. Returns once
/// the server accepts connections.
pub async fn start(config: ServerConfig) -> anyhow::Result<ServerHandle> {
    config.validate()?;
    let inputs = load::load(&config).await?;
    let parts = assemble::assemble(&config, inputs).await?;
    let started = spawn::spawn(&config, parts).await?;
    Ok(ServerHandle {
        local_addr: started.local_addr,
        state: started.state,
        token: started.token,
        supervisor: started.supervisor,
    })
}

/// A running server.
pub struct ServerHandle {
    local_addr: SocketAddr,
    state: Arc<ServerState>,
    token: token::ResolvedToken,
    supervisor: Supervisor,
}

impl ServerHandle {
    /// The bound address (useful with port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// `ws://…/v1/stream` for this server.
    pub fn stream_url(&self) -> String {
        format!("ws://{}/v1/stream", self.local_addr)
    }

    /// Shared state (subjects, counters).
    pub fn state(&self) -> &Arc<ServerState> {
        &self.state
    }

    /// The control token clients present to change the server.
    pub fn control_token(&self) -> &ControlToken {
        &self.token.token
    }

    /// The token, whether this start created it, and its file.
    pub fn token_info(&self) -> &token::ResolvedToken {
        &self.token
    }

    /// `ws://…/v1/stream?token=…`: a stream URL with control access.
    pub fn control_stream_url(&self) -> String {
        format!("{}?token={}", self.stream_url(), self.token.token.reveal())
    }

    /// Stops every task and thread in order and waits for them (see [`spawn`]): client
    /// connections close first, the recording is finished last.
    pub async fn shutdown(self) {
        self.supervisor.shutdown().await;
    }
}
