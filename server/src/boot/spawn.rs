//! Start, step 3: open the outputs (recording, listener) and start every task and thread
//! under one [`Supervisor`], which also stops them, in order:
//!
//! ```text
//!  1. listener stops accepting; client sessions are told to close (WebSocket 1001) and
//!     unfinished requests are dropped; wait (≤ DRAIN_TIMEOUT) until every connection is gone
//!  2. the engine's loop (tick, foot plants, source_status) and replay sources: stopped and
//!     awaited
//!  3. live-source threads and the mapper: stopped and joined
//!  4. recorder thread joined, then the recording finished (its last writer is gone)
//! ```
//!
//! Like axum's graceful shutdown: no new connections, open ones finish, then the rest.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::net::TcpListener;
use tokio::sync::{broadcast, watch};
use tokio::task::JoinHandle;

use super::assemble::{Assembly, SourceRunner};
use super::load::Loaded;
use crate::config::ServerConfig;
use crate::limits::ConnectionLimiter;
use crate::live::{self, LiveContext, LiveFeed};
use crate::recorder::Recorder;
use crate::state::{ClusterView, ServerState};
use crate::{access, http, limits, stats, tick_task, token};
use rigcast_engine::slot::FrameWriter;
use rigcast_engine::tick::{EngineCommand, TickContext};
use rigcast_engine::{Engine, EngineParts};

/// Frames kept per client before it counts as lagging: about two seconds at the default rate
/// with one subject.
const BROADCAST_CAPACITY: usize = 128;

/// Longest shutdown waits for open connections to close.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(2);

/// Owns every task and thread of a running server and stops them in order.
pub struct Supervisor {
    /// Stage 1: the listener and the client sessions.
    connections_stop: watch::Sender<bool>,
    listener: JoinHandle<()>,
    connections: Arc<ConnectionLimiter>,
    /// Stage 2: the engine's loop and replays.
    engine_stop: watch::Sender<bool>,
    engine_tasks: Vec<JoinHandle<()>>,
    /// Stage 3: live sources and the mapper.
    stop_threads: Arc<AtomicBool>,
    /// The mapper's queue (for its `Shutdown`).
    mapper: std::sync::mpsc::Sender<EngineCommand>,
    threads: Vec<std::thread::JoinHandle<()>>,
    /// Live threads started while running (relayed subjects the cluster found).
    late_threads: Arc<std::sync::Mutex<Vec<std::thread::JoinHandle<()>>>>,
    /// Stage 4.
    recorder: Option<(Arc<Recorder>, std::thread::JoinHandle<()>)>,
}

/// A started server's parts, for [`crate::ServerHandle`].
pub(crate) struct Started {
    pub local_addr: std::net::SocketAddr,
    pub state: Arc<ServerState>,
    pub token: token::ResolvedToken,
    pub supervisor: Supervisor,
}

/// Opens the recording and the listener, then starts sources, mapper, recorder, the engine's
/// loop, the cluster's tasks and the listener.
pub(crate) async fn spawn(config: &ServerConfig, parts: Assembly) -> anyhow::Result<Started> {
    let recorder = open_recorder(config).await?;
    let listener = TcpListener::bind(config.listen)
        .await
        .with_context(|| format!("cannot listen on {}", config.listen))?;
    let local_addr = listener.local_addr()?;
    let (connections_stop, connections_rx) = watch::channel(false);
    let (engine_stop, engine_rx) = watch::channel(false);
    let (mapper, mapper_rx) = std::sync::mpsc::channel();
    let forwarder =
        (parts.cluster.as_ref()).map(|link| Arc::new(link.forwarder(parts.token.token.clone())));
    let changes_to_forward = forwarder
        .clone()
        .map(|f| f as Arc<dyn crate::state::ChangeForwarder>);
    let session_ends = (local_addr, connections_rx);
    let state = server_state(config, &parts, session_ends, &recorder, changes_to_forward);
    let state = Arc::new(state);
    let stops = (connections_stop, engine_stop);
    let mut supervisor = Supervisor::new(stops, state.connections.clone(), mapper.clone());
    // The engine writes the sources' slots; the sources hand their poses over through doors.
    let mut fed = Vec::new();
    for source in parts.sources {
        fed.push(supervisor.spawn_source(source, &state, recorder.as_ref(), &engine_rx)?);
    }
    supervisor.spawn_thread("rigcast-mapper".into(), {
        let mapper = parts.mapper;
        move || mapper.run(mapper_rx)
    })?;
    if let Some(rec) = recorder {
        supervisor.spawn_recorder(rec, parts.subjects.clone(), config.rate_hz)?;
    }
    let engine = EngineStart {
        subjects: parts.subjects,
        performers: parts.performers,
        vmc: parts.vmc,
        fed,
        rate_hz: config.rate_hz,
    };
    let run = engine.run(&state, mapper, parts.inbox, parts.wake, engine_rx);
    supervisor.engine_tasks.push(tokio::spawn(run));
    if let (Some(link), Some(forwarder)) = (parts.cluster, forwarder) {
        supervisor.spawn_cluster(link, &state, forwarder);
    }
    supervisor.listener = tokio::spawn(http::run_listener(listener, state.clone()));
    Ok(Started {
        local_addr,
        state,
        token: parts.token,
        supervisor,
    })
}

/// The recording, when one is configured (created off the async threads: it writes a file).
async fn open_recorder(config: &ServerConfig) -> anyhow::Result<Option<Arc<Recorder>>> {
    let Some(path) = config.record.clone() else {
        return Ok(None);
    };
    let recorder = tokio::task::spawn_blocking(move || Recorder::create(&path)).await??;
    Ok(Some(Arc::new(recorder)))
}

/// The state every session, relay and service shares. `listen` is the listener's address
/// (its scope decides who is trusted) and the watch that tells sessions to close.
fn server_state(
    config: &ServerConfig,
    parts: &Assembly,
    listen: (std::net::SocketAddr, watch::Receiver<bool>),
    recorder: &Option<Arc<Recorder>>,
    forwarder: Option<Arc<dyn crate::state::ChangeForwarder>>,
) -> ServerState {
    let (local_addr, shutdown) = listen;
    let subjects = &parts.subjects;
    let (frames, _) = broadcast::channel(BROADCAST_CAPACITY * subjects.len().max(1));
    ServerState {
        subject_list: Arc::new(rigcast_engine::subject_list::SubjectList::new(
            subjects.clone(),
        )),
        frames,
        events: parts.events.clone(),
        stats: Arc::new(stats::Stats::default()),
        rate_hz: config.rate_hz,
        next_client_id: AtomicU64::new(1),
        shutdown,
        inbox: parts.inbox.clone(),
        policy: access::AccessPolicy::new(
            parts.token.token.clone(),
            access::BindScope::of(&local_addr),
            &config.access.allowed_origins,
            &config.access.allowed_hosts,
        ),
        connections: limits::ConnectionLimiter::new(max_connections(config)),
        fd_limit: limits::fd_limit(),
        stalled_client_timeout: Duration::from_secs_f64(config.limits.stalled_client_timeout_secs),
        recorder: recorder.as_ref().map(|r| r.health()),
        cluster: parts.cluster.as_ref().map(|link| ClusterView {
            site: link.cluster.config.site.clone(),
            mapping_counts: link.cluster.mapping_counts.clone(),
        }),
        forwarder,
    }
}

/// What the engine starts from: the subjects, the performers, the VMC output and the sources'
/// slots (subject, slot, whether its poses bring the tick forward).
struct EngineStart {
    subjects: Arc<Vec<Arc<rigcast_engine::subject::Subject>>>,
    performers: Vec<rigcast_engine::performer::Performer>,
    vmc: Option<(std::net::UdpSocket, Vec<rigcast_engine::tick::VmcTarget>)>,
    fed: Vec<(u32, FrameWriter, bool)>,
    rate_hz: f64,
}

impl EngineStart {
    /// The engine's loop (tick, foot plants, source status), writing into the state's frame
    /// broadcast and counters.
    fn run(
        self,
        state: &ServerState,
        mapper: std::sync::mpsc::Sender<EngineCommand>,
        inbox: rigcast_engine::inbox::Inbox,
        wake: Arc<tokio::sync::Notify>,
        stop: watch::Receiver<bool>,
    ) -> impl std::future::Future<Output = ()> {
        let (vmc_socket, vmc) = self.vmc.unzip();
        let mut engine = Engine::new(
            EngineParts {
                tick: TickContext {
                    subjects: self.subjects,
                    vmc: vmc.unwrap_or_default(),
                    performers: self.performers,
                },
                rate_hz: self.rate_hz,
                subjects: state.subject_list.clone(),
            },
            std::time::Instant::now(),
        );
        for (subject, tx, wakes) in self.fed {
            engine.feed(subject, tx, wakes);
        }
        let out = tick_task::HostOutput {
            frames: state.frames.clone(),
            vmc_socket,
            stats: state.stats.clone(),
        };
        let events = state.events.clone();
        tick_task::run_engine(engine, out, events, mapper, inbox, wake, stop)
    }
}

/// The configured connection cap, or what the open-file limit allows.
fn max_connections(config: &ServerConfig) -> usize {
    let fd_cap = limits::default_max_connections(limits::fd_limit());
    match config.limits.max_connections {
        Some(n) if n > fd_cap => {
            tracing::warn!(
                "max_connections {n} exceeds what the open-file limit allows; using {fd_cap}"
            );
            fd_cap
        }
        Some(n) => n,
        None => fd_cap,
    }
}

impl Supervisor {
    /// A supervisor with nothing started yet; `stops` are the watches of stages 1 and 2.
    fn new(
        stops: (watch::Sender<bool>, watch::Sender<bool>),
        connections: Arc<ConnectionLimiter>,
        mapper: std::sync::mpsc::Sender<EngineCommand>,
    ) -> Supervisor {
        let (connections_stop, engine_stop) = stops;
        Supervisor {
            connections_stop,
            listener: tokio::spawn(std::future::ready(())),
            connections,
            engine_stop,
            engine_tasks: Vec::new(),
            stop_threads: Arc::new(AtomicBool::new(false)),
            mapper,
            threads: Vec::new(),
            late_threads: Arc::default(),
            recorder: None,
        }
    }

    /// A replay becomes a task; a live source a thread (its `next_frame` blocks). Each hands
    /// its poses to the engine through a door; returns what the engine is fed for it (the
    /// subject, its slot, whether its poses bring the tick forward: cameras').
    fn spawn_source(
        &mut self,
        source: SourceRunner,
        state: &ServerState,
        recorder: Option<&Arc<Recorder>>,
        engine_rx: &watch::Receiver<bool>,
    ) -> anyhow::Result<(u32, FrameWriter, bool)> {
        let SourceRunner {
            subject,
            tx,
            loaded,
        } = source;
        let id = subject.id;
        let wakes = matches!(&loaded, Loaded::Live { kind, .. }
            if *kind == rigcast_protocol::SourceKind::Webcam);
        let door = state.inbox.door(subject.clone(), wakes);
        match loaded {
            Loaded::Replay { player, speed, .. } => {
                let task =
                    crate::replay_task::run_replay_source(player, speed, door, engine_rx.clone());
                let task = crate::fault::guard_source_task(task, subject);
                self.engine_tasks.push(tokio::spawn(task));
            }
            Loaded::Live { mut source, .. } => {
                if let Some(rec) = recorder {
                    source.set_raw_tap(Some(Box::new(rec.tap(subject.id))));
                }
                let name = format!("rigcast-live-{}", subject.id);
                let guarded = subject.clone();
                let ctx = LiveContext {
                    subject,
                    feed: LiveFeed::Engine(door),
                    subjects: state.subject_list.clone(),
                    events: state.events.clone(),
                    inbox: state.inbox.clone(),
                    recorder: recorder.cloned(),
                    stop: self.stop_threads.clone(),
                };
                self.spawn_thread(name, move || {
                    crate::fault::guard_source_thread(|| live::run_live(source, ctx), guarded)
                })?;
            }
        }
        Ok((id, tx, wakes))
    }

    /// The recorder's thread, which samples `subjects` at `rate_hz` until the threads stop.
    fn spawn_recorder(
        &mut self,
        rec: Arc<Recorder>,
        subjects: Arc<Vec<Arc<rigcast_engine::subject::Subject>>>,
        rate_hz: f64,
    ) -> anyhow::Result<()> {
        let (r, stop) = (rec.clone(), self.stop_threads.clone());
        let thread = std::thread::Builder::new()
            .name("rigcast-recorder".into())
            .spawn(move || r.run(&subjects, rate_hz, &stop))
            .context("cannot start the recorder thread")?;
        self.recorder = Some((rec, thread));
        Ok(())
    }

    /// Cluster mode: the relays and the publisher, with the forwarder the state holds.
    fn spawn_cluster(
        &mut self,
        link: crate::cluster::ClusterLink,
        state: &Arc<ServerState>,
        forwarder: Arc<crate::cluster::Forwarder>,
    ) {
        let live = crate::cluster::LiveThreads {
            stop: self.stop_threads.clone(),
            threads: self.late_threads.clone(),
        };
        self.engine_tasks.extend(link.spawn(state, live, forwarder));
    }

    fn spawn_thread(
        &mut self,
        name: String,
        run: impl FnOnce() + Send + 'static,
    ) -> anyhow::Result<()> {
        let thread = std::thread::Builder::new()
            .name(name.clone())
            .spawn(run)
            .with_context(|| format!("cannot start the thread {name}"))?;
        self.threads.push(thread);
        Ok(())
    }

    /// Stops everything in order (see the module doc) and waits for it.
    pub async fn shutdown(self) {
        // A send fails only when every receiver is gone: then nobody is left to stop.
        let _ = self.connections_stop.send(true);
        // A task that panicked has nothing left to stop; its panic was already reported.
        let _ = self.listener.await;
        self.connections.wait_until_idle(DRAIN_TIMEOUT).await;
        // As above: no receiver left means nothing left to stop.
        let _ = self.engine_stop.send(true);
        for task in self.engine_tasks {
            // A panicked task has already reported its panic and has nothing left to stop.
            let _ = task.await;
        }
        self.stop_threads.store(true, Ordering::Relaxed);
        // Fails only when the mapper has already stopped.
        let _ = self.mapper.send(EngineCommand::Shutdown);
        let mut threads = self.threads;
        if let Ok(mut late) = self.late_threads.lock() {
            threads.append(&mut late);
        }
        let recorder = self.recorder;
        // Joining blocks; a panicked thread's error is its (already printed) panic.
        let _ = tokio::task::spawn_blocking(move || {
            for t in threads {
                // Err is a panic, already printed by the panic hook.
                let _ = t.join();
            }
            if let Some((rec, thread)) = recorder {
                // As above; the recording is still finished below.
                let _ = thread.join();
                // The live threads (and their taps) are gone, so this is the last handle.
                if let Ok(rec) = Arc::try_unwrap(rec) {
                    rec.finish();
                } else {
                    tracing::warn!("recording still shared at shutdown; flushed only");
                }
            }
        })
        .await;
    }
}
