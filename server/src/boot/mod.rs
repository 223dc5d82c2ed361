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

pub(crate) use load::unique_name;
pub use spawn::Supervisor;

use crate::config::ServerConfig;
use crate::ServerHandle;

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
