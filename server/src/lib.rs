//! # rigcast-server — the `rigcast` binary's library
//!
//! Runs the engine and its outputs inside a tokio runtime:
//!
//! ```text
//!  SourceSpec ─load─▶ Replay task ─┐
//!  live source thread (VMC, serial, video) ─┴─▶ watch<Frame> (latest wins, one per source)
//!                                                   │
//!                 tick: tokio interval @ rate_hz, MissedTickBehavior::Skip
//!                   │ performers: Mapping::apply into preallocated target poses
//!                   │   (mappings built by the mapper thread, never awaited by the tick)
//!                   │ encode each subject once → Bytes (shared)      VMC bundles → UDP
//!                   ▼                                                 (≤1500 B each)
//!             broadcast<OutFrame>  (bounded; never awaited by the tick) ──▶ recorder
//!                   │
//!        ┌──────────┼───────────┐
//!   client task  client task  client task   (one per WebSocket; a lagging one gets
//!        │            │            │          `lagged` + missed_frames, stays connected)
//!   GET /v1/stream  (same listener also serves GET /v1/status and the viewer's files;
//!                    every request passes the connection cap (limits.rs) and the
//!                    Origin/Host/token checks (access.rs) first)
//! ```
//!
//! [`start`] runs all of it in-process (tests use `127.0.0.1:0`); the binary's subcommands live
//! in [`cmd`] and are listed in [`cli::Command`].
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used))]

pub mod access;
pub mod calibration;
pub mod character;
pub mod cli;
pub mod clients;
pub mod cluster;
pub mod cmd;
pub mod config;
pub mod demo;
pub mod engine;
pub mod graft_live;
pub mod http;
pub mod limits;
pub mod live;
pub mod mapper;
pub mod mapping_store;
pub mod performer;
pub mod recorder;
pub mod skeleton_wire;
pub mod state;
pub mod stats;
pub mod subject;
pub mod token;
pub mod translated;
pub mod vmc_pose;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

use anyhow::Context;
use tokio::net::TcpListener;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

pub use config::{
    AccessConfig, LimitsConfig, OnLost, PerformerSpec, ReplaySettings, ServerConfig, SourceSpec,
    TargetSpec, VmcBoneNames,
};
pub use token::{ControlToken, TokenSetting};

use engine::{EngineCommand, TickContext, VmcTarget};
use live::LiveContext;
use mapper::{Mapper, PerformerPlan, SourceExtra};
use performer::Performer;
use recorder::Recorder;
use rigcast_retarget::mapping::parse_mapping_file;
use rigcast_retarget::RootMotion;
use rigcast_sources::live::LiveSource;
use rigcast_sources::serial::{CalibrationHandle, SerialImuConfig, SerialImuSource};
use rigcast_sources::vmc_in::{VmcConfig, VmcSource};
use rigcast_sources::{Replay, ReplayOptions};
use state::ServerState;
use subject::Subject;

/// Frames kept per client before it counts as lagging: about two seconds at the default rate
/// with one subject.
const BROADCAST_CAPACITY: usize = 128;

/// A running server.
pub struct ServerHandle {
    local_addr: SocketAddr,
    shutdown: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
    threads: Vec<std::thread::JoinHandle<()>>,
    stop_threads: Arc<AtomicBool>,
    commands: mpsc::Sender<EngineCommand>,
    recorder: Option<(Arc<Recorder>, std::thread::JoinHandle<()>)>,
    state: Arc<ServerState>,
    token: token::ResolvedToken,
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

    /// Stops every task and thread and waits for them; finishes the recording. Client tasks
    /// are told to close their connections.
    pub async fn shutdown(self) {
        let _ = self.shutdown.send(true);
        self.stop_threads.store(true, Ordering::Relaxed);
        let _ = self.commands.send(EngineCommand::Shutdown).await;
        for t in self.tasks {
            let _ = t.await;
        }
        let threads = self.threads;
        let recorder = self.recorder;
        let _ = tokio::task::spawn_blocking(move || {
            for t in threads {
                let _ = t.join();
            }
            if let Some((rec, thread)) = recorder {
                let _ = thread.join();
                // The live threads (and their taps) are gone, so this is the last handle.
                if let Ok(rec) = Arc::try_unwrap(rec) {
                    rec.finish();
                } else {
                    eprintln!("rigcast: recording still shared at shutdown; flushed only");
                }
            }
        })
        .await;
    }
}

/// A loaded source, before it becomes a subject.
enum Loaded {
    Replay {
        player: Replay,
        speed: f64,
        clip_poses: Arc<Vec<rigcast_retarget::Pose>>,
        /// A VRM file's humanoid map (ground truth for its roles).
        truth: Option<Vec<(String, String)>>,
    },
    Live {
        source: Box<dyn LiveSource>,
        kind: &'static str,
        listen: Option<SocketAddr>,
        /// Set for calibratable sources (serial IMU suits).
        calibration: Option<CalibrationHandle>,
    },
}

/// A loaded character.
struct LoadedTarget {
    name: String,
    skeleton: Arc<rigcast_retarget::Skeleton>,
    reference: Option<rigcast_retarget::Pose>,
    /// A VRM file's humanoid map (ground truth for its roles).
    truth: Option<Vec<(String, String)>>,
}

/// Loads the sources and characters, binds the listener and starts the engine. Returns once
/// the server accepts connections.
pub async fn start(config: ServerConfig) -> anyhow::Result<ServerHandle> {
    config.validate()?;
    let cluster = match &config.cluster {
        Some(c) => Some(Arc::new(cluster::Cluster::connect(c).await?)),
        None => None,
    };
    let remote_entries = match &cluster {
        Some(c) => c.remote_entries().await?,
        None => Vec::new(),
    };
    // A node that relays other nodes' subjects needs no demo of its own.
    let defaulted = config.sources.is_empty() && remote_entries.is_empty();
    let specs = if defaulted {
        vec![SourceSpec::EmbeddedDemo]
    } else {
        config.sources.clone()
    };
    let mut performer_specs = config.performers.clone();
    if defaulted && performer_specs.is_empty() {
        // The default demo: the bundled walk and the built-in character retargeted from it.
        performer_specs.push(config::PerformerSpec::target_file(format!(
            "{}mannequin",
            config::BUILTIN_PREFIX
        )));
    }
    let mut loaded = Vec::new();
    let mut names = Vec::new();
    // Files, serial ports, ffmpeg and ONNX Runtime block: none of it runs on a runtime worker.
    for spec in specs {
        let (name, l, skeleton) = tokio::task::spawn_blocking(move || load_source(spec)).await??;
        names.push(unique_name(&names, name));
        loaded.push((l, skeleton));
    }
    let mut relays = Vec::new();
    if let Some(c) = &cluster {
        for e in &remote_entries {
            let (source, tx) = cluster::RemoteSource::new(e, c.config.lost_after())
                .with_context(|| format!("cluster subject {}", e.relayed_name()))?;
            let skeleton = source
                .skeleton()
                .context("a remote source has a skeleton")?;
            let subject = c.config.frame_subject(&e.site, &cluster::token(&e.name));
            relays.push((loaded.len() as u32, subject, tx));
            names.push(unique_name(&names, e.relayed_name()));
            let live = Loaded::Live {
                source: Box::new(source),
                kind: cluster::REMOTE_KIND,
                listen: None,
                calibration: None,
            };
            loaded.push((live, skeleton));
        }
    }
    let mut targets = Vec::new();
    for p in &performer_specs {
        let p = p.clone();
        targets.push(tokio::task::spawn_blocking(move || load_target(&p)).await??);
    }
    let token_setting = config.access.token.clone();
    let token = tokio::task::spawn_blocking(move || token_setting.resolve()).await??;

    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    let (events_tx, _) = broadcast::channel::<String>(EVENTS_CAPACITY);
    let mut subjects = Vec::new();
    let mut senders = Vec::new();
    let mut extras = HashMap::new();
    for (i, ((l, skeleton), name)) in loaded.iter().zip(&names).enumerate() {
        let mut truth = None;
        let mut replay_poses = None;
        let (kind, listen, calibration) = match l {
            Loaded::Replay {
                clip_poses,
                truth: t,
                ..
            } => {
                truth = t.clone();
                replay_poses = Some(clip_poses.clone());
                extras.insert(
                    i as u32,
                    SourceExtra {
                        reference: clip_poses.get(clip_poses.len() / 2).cloned(),
                        poses: clip_poses.clone(),
                    },
                );
                ("replay", None, None)
            }
            Loaded::Live {
                kind,
                listen,
                calibration,
                ..
            } => (*kind, *listen, calibration.clone()),
        };
        let (subject, tx) = Subject::with_kind(
            i as u32,
            name.clone(),
            skeleton.clone(),
            kind,
            Vec::new(),
            config.vmc_bone_names,
        );
        let subject = subject
            .with_listen_addr(listen)
            .with_calibration(calibration)
            .with_truth(truth);
        let subject = match &replay_poses {
            Some(poses) => subject.with_moving_bones(poses),
            None => subject,
        };
        subjects.push(Arc::new(subject));
        senders.push(tx);
    }
    let num_sources = subjects.len();
    let mut plans = Vec::new();
    let mut target_txs = Vec::new();
    for (p, t) in performer_specs.iter().zip(targets) {
        let inputs: Vec<u32> = if p.sources.is_empty() {
            vec![0]
        } else {
            p.sources
                .iter()
                .map(|n| {
                    names
                        .iter()
                        .position(|m| m == n)
                        .map(|i| i as u32)
                        .with_context(|| {
                            format!(
                                "performer {}: no source named {n:?} (sources: {names:?})",
                                t.name
                            )
                        })
                })
                .collect::<anyhow::Result<_>>()?
        };
        if inputs.len() > performer::MAX_INPUTS {
            anyhow::bail!(
                "performer {}: at most {} sources per target",
                t.name,
                performer::MAX_INPUTS
            );
        }
        let all_names: Vec<String> = subjects.iter().map(|s| s.info().name).collect();
        let name = unique_name(&all_names, p.name.clone().unwrap_or(t.name));
        let (subject, tx) = Subject::with_kind(
            subjects.len() as u32,
            name,
            t.skeleton,
            "target",
            inputs,
            config.vmc_bone_names,
        );
        let subject = Arc::new(subject.with_truth(t.truth));
        let overrides_file = match &p.mapping {
            Some(path) => {
                let path2 = path.clone();
                let text = tokio::task::spawn_blocking(move || std::fs::read_to_string(path2))
                    .await?
                    .with_context(|| format!("cannot read the mapping file {}", path.display()))?;
                Some(
                    parse_mapping_file(&text)
                        .with_context(|| format!("mapping file {}", path.display()))?,
                )
            }
            None => None,
        };
        let graft = match p.graft.as_ref().map(|g| &g.lower) {
            None => None,
            Some(config::LowerSpec::Source(_)) => Some(graft_live::LowerInput::Source),
            Some(config::LowerSpec::Clip(path)) => {
                let path = path.clone();
                let clip = tokio::task::spawn_blocking(move || rigcast_sources::load_clip(&path))
                    .await?
                    .context("the graft's lower-body clip")?;
                Some(graft_live::LowerInput::Clip(Arc::new(clip)))
            }
        };
        plans.push(PerformerPlan {
            graft,
            target: subject.clone(),
            target_reference: t.reference,
            overrides_file,
            session: Default::default(),
            root_motion: if p.in_place {
                RootMotion::InPlace
            } else {
                RootMotion::Scaled
            },
            foot_lock: p.foot_lock,
            mailbox: Default::default(),
        });
        target_txs.push((tx, p.on_lost.unwrap_or(config.on_lost)));
        subjects.push(subject);
    }
    let subjects = Arc::new(subjects);
    let performers: Vec<Performer> = plans
        .iter()
        .zip(target_txs)
        .map(|(plan, (tx, on_lost))| {
            Performer::new(
                plan.target.clone(),
                tx,
                plan.target
                    .inputs
                    .iter()
                    .map(|id| subjects[*id as usize].clone())
                    .collect(),
                plan.mailbox.clone(),
                on_lost,
            )
        })
        .collect();
    let mut mapper = Mapper::new(
        subjects.clone(),
        plans,
        extras,
        config.mapping_cache_dir.clone(),
        config.rate_hz,
        events_tx.clone(),
    )
    .with_max_cache_entries(config.limits.mapping_cache_max_entries);
    let mapper = tokio::task::spawn_blocking(move || {
        mapper.build_all();
        mapper
    })
    .await?;

    let vmc = if config.vmc_out.is_empty() {
        None
    } else {
        let default_subject = subjects.iter().position(|s| s.is_target()).unwrap_or(0);
        let mut targets = Vec::new();
        for entry in &config.vmc_out {
            let (addr, subject_index) = match entry.rsplit_once('@') {
                Some((addr, name)) => (
                    addr,
                    subjects
                        .iter()
                        .position(|s| s.info().name == name)
                        .with_context(|| {
                            format!("VMC output {entry:?}: no subject named {name:?}")
                        })?,
                ),
                None => (entry.as_str(), default_subject),
            };
            let resolved = tokio::net::lookup_host(addr)
                .await
                .with_context(|| format!("cannot resolve VMC receiver {addr:?}"))?
                .next()
                .with_context(|| format!("VMC receiver {addr:?} resolves to no address"))?;
            targets.push(VmcTarget {
                addr: resolved,
                subject_index,
            });
        }
        let socket = std::net::UdpSocket::bind(("0.0.0.0", 0)).context("binding VMC socket")?;
        socket
            .set_nonblocking(true)
            .context("making VMC socket non-blocking")?;
        Some((socket, targets))
    };

    let recorder = match config.record.clone() {
        Some(path) => Some(Arc::new(
            tokio::task::spawn_blocking(move || Recorder::create(&path)).await??,
        )),
        None => None,
    };

    let listener = TcpListener::bind(config.listen)
        .await
        .with_context(|| format!("cannot listen on {}", config.listen))?;
    let local_addr = listener.local_addr()?;
    let policy = access::AccessPolicy::new(
        token.token.clone(),
        access::BindScope::of(&local_addr),
        &config.access.allowed_origins,
        &config.access.allowed_hosts,
    );
    let fd_limit = limits::fd_limit();
    let fd_cap = limits::default_max_connections(fd_limit);
    let max_connections = match config.limits.max_connections {
        Some(n) if n > fd_cap => {
            eprintln!(
                "rigcast: warning: max_connections {n} exceeds what the open-file limit allows; using {fd_cap}"
            );
            fd_cap
        }
        Some(n) => n,
        None => fd_cap,
    };

    let (frames_tx, _) = broadcast::channel(BROADCAST_CAPACITY * subjects.len().max(1));
    let (commands_tx, commands_rx) = mpsc::channel(64);
    let stats = Arc::new(stats::Stats::default());
    let state = Arc::new(ServerState {
        subjects: subjects.clone(),
        frames: frames_tx.clone(),
        events: events_tx.clone(),
        stats: stats.clone(),
        rate_hz: config.rate_hz,
        next_client_id: AtomicU64::new(1),
        shutdown: shutdown_rx.clone(),
        commands: commands_tx.clone(),
        policy,
        connections: limits::ConnectionLimiter::new(max_connections),
        fd_limit,
        stalled_client_timeout: std::time::Duration::from_secs_f64(
            config.limits.stalled_client_timeout_secs,
        ),
        recorder: recorder.as_ref().map(|r| r.health()),
    });

    let stop_threads = Arc::new(AtomicBool::new(false));
    let mut tasks = Vec::new();
    let mut threads = Vec::new();
    for (((l, _), tx), subject) in loaded
        .into_iter()
        .zip(senders)
        .zip(subjects.iter().take(num_sources).cloned())
    {
        match l {
            Loaded::Replay { player, speed, .. } => {
                tasks.push(tokio::spawn(engine::run_replay_source(
                    player,
                    speed,
                    tx,
                    subject,
                    shutdown_rx.clone(),
                )));
            }
            Loaded::Live { mut source, .. } => {
                if let Some(rec) = &recorder {
                    source.set_raw_tap(Some(Box::new(rec.tap(subject.id))));
                }
                let ctx = LiveContext {
                    subject,
                    tx,
                    subjects: subjects.clone(),
                    events: events_tx.clone(),
                    commands: commands_tx.clone(),
                    recorder: recorder.clone(),
                    stop: stop_threads.clone(),
                };
                threads.push(
                    std::thread::Builder::new()
                        .name(format!("rigcast-live-{}", ctx.subject.id))
                        .spawn(move || live::run_live(source, ctx))
                        .context("cannot start a live source thread")?,
                );
            }
        }
    }
    threads.push(
        std::thread::Builder::new()
            .name("rigcast-mapper".into())
            .spawn(move || mapper.run(commands_rx))
            .context("cannot start the mapper thread")?,
    );
    let recorder = match recorder {
        Some(rec) => {
            let r = rec.clone();
            let subs = subjects.clone();
            let stop = stop_threads.clone();
            let rate = config.rate_hz;
            let t = std::thread::Builder::new()
                .name("rigcast-recorder".into())
                .spawn(move || r.run(&subs, rate, &stop))
                .context("cannot start the recorder thread")?;
            Some((rec, t))
        }
        None => None,
    };
    tasks.push(tokio::spawn(engine::run_tick(
        TickContext {
            subjects: subjects.clone(),
            frames: frames_tx,
            stats,
            rate_hz: config.rate_hz,
            vmc,
            performers,
        },
        shutdown_rx.clone(),
    )));
    tasks.push(tokio::spawn(run_source_status(
        subjects,
        events_tx,
        shutdown_rx.clone(),
    )));
    if let Some(c) = &cluster {
        for (id, subject, tx) in relays {
            let relay = cluster::run_relay(c.client.clone(), subject, id, tx, state.clone());
            tasks.push(tokio::spawn(relay));
        }
        tasks.push(tokio::spawn(cluster::run_publisher(
            c.clone(),
            state.clone(),
        )));
    }
    tasks.push(tokio::spawn(http::run_listener(listener, state.clone())));

    Ok(ServerHandle {
        local_addr,
        shutdown: shutdown_tx,
        tasks,
        threads,
        stop_threads,
        commands: commands_tx,
        recorder,
        state,
        token,
    })
}

/// Control messages queued per client (mapping updates, skeleton changes, source status).
pub(crate) const EVENTS_CAPACITY: usize = 256;

/// Broadcasts `source_status` about once per second.
async fn run_source_status(
    subjects: Arc<Vec<Arc<Subject>>>,
    events: broadcast::Sender<String>,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut interval = tokio::time::interval(std::time::Duration::from_secs(1));
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = shutdown.changed() => break,
        }
        if events.receiver_count() == 0 {
            continue;
        }
        let _ = events.send(source_status_json(&subjects));
    }
}

/// The `source_status` message for `subjects`.
pub fn source_status_json(subjects: &[Arc<Subject>]) -> String {
    rigcast_protocol::ServerMessage::SourceStatus {
        sources: subjects.iter().filter_map(|s| s.source_health()).collect(),
    }
    .to_json()
}

/// `name`, or `name-2`, `name-3`… when taken.
fn unique_name(taken: &[String], name: String) -> String {
    if !taken.contains(&name) {
        return name;
    }
    (2..)
        .map(|i| format!("{name}-{i}"))
        .find(|n| !taken.contains(n))
        .unwrap_or(name)
}

/// Loads a character: a file (its animation only serves as a reference posture) or a
/// built-in.
fn load_target(p: &config::PerformerSpec) -> anyhow::Result<LoadedTarget> {
    match &p.target {
        TargetSpec::Skeleton { skeleton, name } => Ok(LoadedTarget {
            name: name.clone(),
            skeleton: skeleton.clone(),
            reference: None,
            truth: None,
        }),
        TargetSpec::File(path) => {
            let text = path.to_string_lossy();
            if let Some(builtin) = text.strip_prefix(config::BUILTIN_PREFIX) {
                let skeleton = character::builtin(builtin).with_context(|| {
                    format!(
                        "unknown built-in character {builtin:?}; expected one of {:?}",
                        character::BUILTIN_NAMES
                    )
                })?;
                return Ok(LoadedTarget {
                    name: builtin.to_string(),
                    skeleton: Arc::new(skeleton),
                    reference: None,
                    truth: None,
                });
            }
            let (clip, truth) = rigcast_sources::load_clip(path)
                .map(|c| (c, cmd::map::vrm_truth(path)))
                .with_context(|| format!("cannot load target character {}", path.display()))?;
            let name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| clip.name.clone());
            Ok(LoadedTarget {
                name,
                reference: clip.poses.get(clip.poses.len() / 2).cloned(),
                skeleton: clip.skeleton,
                truth,
            })
        }
    }
}

/// Loads a source: its subject name, what runs it, and its (initial) skeleton. Blocks (files,
/// devices, model loading): call it from `spawn_blocking`.
fn load_source(
    spec: SourceSpec,
) -> anyhow::Result<(String, Loaded, Arc<rigcast_retarget::Skeleton>)> {
    let replay_of = |clip: rigcast_retarget::Clip,
                     settings: ReplaySettings,
                     truth: Option<Vec<(String, String)>>|
     -> anyhow::Result<Loaded> {
        let poses = Arc::new(clip.poses.clone());
        Ok(Loaded::Replay {
            player: replay(clip, settings)?,
            speed: settings.speed,
            clip_poses: poses,
            truth,
        })
    };
    Ok(match spec {
        SourceSpec::ReplayFile {
            path,
            name,
            settings,
        } => {
            let (clip, truth) = rigcast_sources::load_clip(&path)
                .map(|c| (c, cmd::map::vrm_truth(&path)))
                .with_context(|| format!("cannot load source {}", path.display()))?;
            let name = name.unwrap_or_else(|| {
                path.file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| clip.name.clone())
            });
            let sk = clip.skeleton.clone();
            (name, replay_of(clip, settings, truth)?, sk)
        }
        SourceSpec::ReplayClip {
            clip,
            name,
            settings,
        } => {
            let sk = clip.skeleton.clone();
            (
                name.unwrap_or_else(|| clip.name.clone()),
                replay_of(clip, settings, None)?,
                sk,
            )
        }
        SourceSpec::EmbeddedDemo => {
            let clip = demo_clip()?;
            let sk = clip.skeleton.clone();
            (
                "demo".to_string(),
                replay_of(clip, ReplaySettings::default(), None)?,
                sk,
            )
        }
        SourceSpec::Vmc {
            port,
            bind,
            allowed_senders,
            lost_after_secs,
            name,
        } => {
            let mut cfg = VmcConfig::port(port);
            cfg.bind = bind;
            cfg.allowed_senders = allowed_senders;
            if let Some(l) = lost_after_secs {
                cfg.lost_after_secs = l;
            }
            let source = VmcSource::bind(cfg)
                .with_context(|| format!("cannot listen for VMC on UDP {bind} port {port}"))?;
            let listen = source.local_addr();
            let name =
                name.unwrap_or_else(|| format!("vmc:{}", listen.map(|a| a.port()).unwrap_or(port)));
            // Until the sender's own skeleton arrives, the standard humanoid stands in.
            let sk = match source.skeleton() {
                Some(s) => s,
                None => rigcast_sources::live::humanoid::default_humanoid()
                    .context("building the default humanoid")?,
            };
            (
                name,
                Loaded::Live {
                    source: Box::new(source),
                    kind: "vmc",
                    listen,
                    calibration: None,
                },
                sk,
            )
        }
        SourceSpec::Serial { config, name } => {
            let text = std::fs::read_to_string(&config)
                .with_context(|| format!("cannot read serial config {}", config.display()))?;
            let cfg = SerialImuConfig::from_toml(&text)
                .with_context(|| format!("serial config {}", config.display()))?;
            let humanoid = rigcast_sources::live::humanoid::default_humanoid()
                .context("building the default humanoid")?;
            let source = SerialImuSource::open(cfg, humanoid.clone())
                .with_context(|| format!("cannot open the serial suit of {}", config.display()))?;
            let sk = source.skeleton().unwrap_or(humanoid);
            let name = name.unwrap_or_else(|| stem(&config));
            let calibration = Some(source.calibration_handle());
            (
                name,
                Loaded::Live {
                    source: Box::new(source),
                    kind: "serial",
                    listen: None,
                    calibration,
                },
                sk,
            )
        }
        SourceSpec::Webcam { index, name } => {
            let (source, sk) = open_webcam(index)?;
            (
                name.unwrap_or_else(|| format!("webcam:{index}")),
                Loaded::Live {
                    source,
                    kind: "webcam",
                    listen: None,
                    calibration: None,
                },
                sk,
            )
        }
        SourceSpec::Video { path, name } => {
            let (source, sk) = open_video(&path)?;
            (
                name.unwrap_or_else(|| stem(&path)),
                Loaded::Live {
                    source,
                    kind: "video",
                    listen: None,
                    calibration: None,
                },
                sk,
            )
        }
    })
}

fn stem(p: &std::path::Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}

/// Pose estimation on a video file, as a live source (frames released in real time).
fn open_video(
    path: &std::path::Path,
) -> anyhow::Result<(Box<dyn LiveSource>, Arc<rigcast_retarget::Skeleton>)> {
    use rigcast_sources::vision::{FfmpegSource, PipelineConfig, PosePipeline, VisionSource};
    let frames = FfmpegSource::open(path)
        .with_context(|| format!("cannot open video {}", path.display()))?;
    let pipeline = PosePipeline::new(&PipelineConfig::default())
        .context("pose estimation is not set up (run `rigcast setup vision`)")?;
    let sk = pipeline.skeleton().clone();
    let source = VisionSource::new(stem(path), Box::new(frames), pipeline, true);
    Ok((Box::new(source), sk))
}

/// What to tell a user of a build without webcam support.
pub const NO_WEBCAM_HINT: &str = "this rigcast was built without webcam support; rebuild it with \
     `cargo build --release -p rigcast-server --features webcam` (which needs libclang: \
     `sudo apt-get install libclang-dev` on Debian/Ubuntu), or use `--source video:FILE`";

/// Pose estimation on a webcam, as a live source.
#[cfg(feature = "webcam")]
fn open_webcam(
    index: u32,
) -> anyhow::Result<(Box<dyn LiveSource>, Arc<rigcast_retarget::Skeleton>)> {
    use rigcast_sources::vision::{open_webcam, PipelineConfig, PosePipeline, VisionSource};
    let frames = open_webcam(index).with_context(|| format!("cannot open webcam {index}"))?;
    let pipeline = PosePipeline::new(&PipelineConfig::default())
        .context("pose estimation is not set up (run `rigcast setup vision`)")?;
    let sk = pipeline.skeleton().clone();
    // A camera delivers frames as they happen; no pacing needed (realtime = false).
    let source = VisionSource::new(format!("webcam:{index}"), frames, pipeline, false);
    Ok((Box::new(source), sk))
}

/// Without the `webcam` feature: a clear error saying how to get one.
#[cfg(not(feature = "webcam"))]
fn open_webcam(
    index: u32,
) -> anyhow::Result<(Box<dyn LiveSource>, Arc<rigcast_retarget::Skeleton>)> {
    anyhow::bail!("--source webcam:{index}: {NO_WEBCAM_HINT}")
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
