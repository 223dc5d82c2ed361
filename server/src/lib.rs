//! # rigcast-server — the `rigcast` binary's library
//!
//! Runs the engine and its outputs inside a tokio runtime:
//!
//! ```text
//!  SourceSpec ─load─▶ Replay ─source task─▶ watch<Frame> (latest wins, one per subject)
//!                                                   │
//!                 tick: tokio interval @ rate_hz, MissedTickBehavior::Skip
//!                   │ encode each subject once → Bytes (shared)      VMC bundles → UDP
//!                   ▼                                                 (≤1500 B each)
//!             broadcast<OutFrame>  (bounded; never awaited by the tick)
//!                   │
//!        ┌──────────┼───────────┐
//!   client task  client task  client task   (one per WebSocket; a lagging one gets
//!        │            │            │          `lagged` + missed_frames, stays connected)
//!   GET /v1/stream  (same listener also serves GET /v1/status and the viewer's files)
//! ```
//!
//! [`start`] runs all of it in-process (tests use `127.0.0.1:0`); the binary's subcommands live
//! in [`cmd`] and are listed in [`cli::Command`].
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used))]

pub mod cli;
pub mod clients;
pub mod cmd;
pub mod config;
pub mod demo;
pub mod engine;
pub mod http;
pub mod state;
pub mod stats;

use std::net::SocketAddr;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;

use anyhow::Context;
use tokio::net::TcpListener;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

pub use config::{ReplaySettings, ServerConfig, SourceSpec};

use engine::{Subject, TickContext, VmcTarget};
use rigcast_sources::{Replay, ReplayOptions};
use state::ServerState;

/// Frames kept per client before it counts as lagging: about two seconds at the default rate
/// with one subject.
const BROADCAST_CAPACITY: usize = 128;

/// A running server.
pub struct ServerHandle {
    local_addr: SocketAddr,
    shutdown: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
    state: Arc<ServerState>,
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

    /// Stops every task and waits for the engine tasks to finish. Client tasks are told to
    /// close their connections.
    pub async fn shutdown(self) {
        let _ = self.shutdown.send(true);
        for t in self.tasks {
            let _ = t.await;
        }
    }
}

/// Loads the sources, binds the listener and starts the engine. Returns once the server
/// accepts connections.
pub async fn start(config: ServerConfig) -> anyhow::Result<ServerHandle> {
    config.validate()?;
    let specs = if config.sources.is_empty() {
        vec![SourceSpec::EmbeddedDemo]
    } else {
        config.sources.clone()
    };
    let mut players = Vec::new();
    for spec in specs {
        players.push(load_source(spec).await?);
    }

    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    let mut subjects = Vec::new();
    let mut senders = Vec::new();
    for (i, (name, player, _)) in players.iter().enumerate() {
        let (subject, tx) = Subject::new(i as u32, name.clone(), player.skeleton().clone());
        subjects.push(Arc::new(subject));
        senders.push(tx);
    }
    let subjects = Arc::new(subjects);

    let vmc = if config.vmc_out.is_empty() {
        None
    } else {
        let mut targets = Vec::new();
        for addr in &config.vmc_out {
            let resolved = tokio::net::lookup_host(addr.as_str())
                .await
                .with_context(|| format!("cannot resolve VMC receiver {addr:?}"))?
                .next()
                .with_context(|| format!("VMC receiver {addr:?} resolves to no address"))?;
            // One avatar per VMC receiver: the first subject, until targets are configurable.
            targets.push(VmcTarget {
                addr: resolved,
                subject_index: 0,
            });
        }
        let socket = std::net::UdpSocket::bind(("0.0.0.0", 0)).context("binding VMC socket")?;
        socket
            .set_nonblocking(true)
            .context("making VMC socket non-blocking")?;
        Some((socket, targets))
    };

    let listener = TcpListener::bind(config.listen)
        .await
        .with_context(|| format!("cannot listen on {}", config.listen))?;
    let local_addr = listener.local_addr()?;

    let (frames_tx, _) = broadcast::channel(BROADCAST_CAPACITY * subjects.len().max(1));
    let (commands_tx, commands_rx) = mpsc::channel(64);
    let stats = Arc::new(stats::Stats::default());
    let state = Arc::new(ServerState {
        subjects: subjects.clone(),
        frames: frames_tx.clone(),
        stats: stats.clone(),
        rate_hz: config.rate_hz,
        next_client_id: AtomicU64::new(1),
        shutdown: shutdown_rx.clone(),
        commands: commands_tx,
    });

    let mut tasks = Vec::new();
    for ((_, player, speed), (tx, subject)) in players
        .into_iter()
        .zip(senders.into_iter().zip(subjects.iter().cloned()))
    {
        tasks.push(tokio::spawn(engine::run_replay_source(
            player,
            speed,
            tx,
            subject,
            shutdown_rx.clone(),
        )));
    }
    tasks.push(tokio::spawn(engine::run_tick(
        TickContext {
            subjects,
            frames: frames_tx,
            stats,
            rate_hz: config.rate_hz,
            vmc,
        },
        shutdown_rx.clone(),
    )));
    tasks.push(tokio::spawn(engine::run_commands(
        commands_rx,
        shutdown_rx.clone(),
    )));
    tasks.push(tokio::spawn(http::run_listener(listener, state.clone())));

    Ok(ServerHandle {
        local_addr,
        shutdown: shutdown_tx,
        tasks,
        state,
    })
}

/// Loads a source: its subject name, the replay, and its speed (the replay task paces itself).
async fn load_source(spec: SourceSpec) -> anyhow::Result<(String, Replay, f64)> {
    Ok(match spec {
        SourceSpec::ReplayFile {
            path,
            name,
            settings,
        } => {
            let p = path.clone();
            let clip = tokio::task::spawn_blocking(move || rigcast_sources::load_clip(&p))
                .await?
                .with_context(|| format!("cannot load source {}", path.display()))?;
            let name = name.unwrap_or_else(|| {
                path.file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| clip.name.clone())
            });
            (name, replay(clip, settings)?, settings.speed)
        }
        SourceSpec::ReplayClip {
            clip,
            name,
            settings,
        } => (
            name.unwrap_or_else(|| clip.name.clone()),
            replay(clip, settings)?,
            settings.speed,
        ),
        SourceSpec::EmbeddedDemo => {
            let clip = demo_clip()?;
            let settings = ReplaySettings::default();
            ("demo".to_string(), replay(clip, settings)?, settings.speed)
        }
    })
}

fn replay(clip: rigcast_retarget::Clip, settings: ReplaySettings) -> anyhow::Result<Replay> {
    let name = clip.name.clone();
    Replay::new(
        clip,
        ReplayOptions {
            speed: settings.speed,
            looping: settings.looping,
            start_offset_secs: settings.start_offset_secs,
        },
    )
    .with_context(|| format!("cannot replay {name:?}"))
}

/// The bundled demo recording; if it cannot be decoded (a build without it), the procedural
/// demo clip, so `rigcast` with no arguments always shows something.
pub fn demo_clip() -> anyhow::Result<rigcast_retarget::Clip> {
    match rigcast_sources::embedded_demo() {
        Ok(clip) if clip.num_frames() > 0 => Ok(clip),
        Ok(_) => Ok(demo::procedural_clip(120, 30.0)?),
        Err(e) => {
            eprintln!("rigcast: bundled demo unavailable ({e}); using the procedural demo");
            Ok(demo::procedural_clip(120, 30.0)?)
        }
    }
}
