//! Start, step 2: turn what was loaded into the engine's parts — one subject per source and
//! per performer, the performers' plans and the mapper that builds their first mappings, the
//! VMC receivers. Nothing runs yet.

use std::collections::HashMap;
use std::sync::Arc;

use anyhow::Context;
use rigcast_protocol::SourceKind;
use rigcast_retarget::RootMotion;
use tokio::sync::broadcast;

use super::load::{Inputs, Loaded, LoadedPerformer, LoadedSource};
use crate::config::ServerConfig;
use crate::mapper::{Mapper, PerformerPlan, SourceExtra};
use crate::token;
use rigcast_engine::inbox::Inbox;
use rigcast_engine::performer::{self, Performer};
use rigcast_engine::slot::FrameWriter;
use rigcast_engine::subject::{Calibrator, Subject};
use rigcast_engine::tick::VmcTarget;

/// A source subject with what feeds it.
pub(crate) struct SourceRunner {
    pub subject: Arc<Subject>,
    pub tx: FrameWriter,
    pub loaded: Loaded,
}

/// The engine's parts, ready to spawn.
pub(crate) struct Assembly {
    /// Sources first (ids `0..sources.len()`), then targets.
    pub subjects: Arc<Vec<Arc<Subject>>>,
    pub sources: Vec<SourceRunner>,
    pub performers: Vec<Performer>,
    /// First mappings built; runs on its own thread from here on.
    pub mapper: Mapper,
    /// The VMC output socket and its receivers (`None` without receivers).
    pub vmc: Option<(std::net::UdpSocket, Vec<VmcTarget>)>,
    pub events: broadcast::Sender<rigcast_engine::events::Event>,
    /// Where the sources, the mapper and the sessions leave what the engine should learn of
    /// (the first mappings wait there already).
    pub inbox: Inbox,
    /// Notified when something comes into the inbox that the engine's loop should take now.
    pub wake: Arc<tokio::sync::Notify>,
    pub token: token::ResolvedToken,
    /// Cluster mode: relays and publisher to start.
    pub cluster: Option<crate::cluster::ClusterLink>,
}

/// Builds the subjects, performers and mapper of `inputs`, and resolves the VMC receivers.
pub(crate) async fn assemble(config: &ServerConfig, inputs: Inputs) -> anyhow::Result<Assembly> {
    let (events, _) = broadcast::channel(rigcast_engine::events::EVENTS_CAPACITY);
    let wake = Arc::new(tokio::sync::Notify::new());
    let inbox = Inbox::new({
        let wake = wake.clone();
        move || wake.notify_one()
    });
    let names: Vec<String> = inputs.sources.iter().map(|s| s.name.clone()).collect();
    let (sources, extras) = source_runners(inputs.sources, config);
    let mut subjects: Vec<Arc<Subject>> = sources.iter().map(|r| r.subject.clone()).collect();
    let mut plans = Vec::new();
    let mut target_txs = Vec::new();
    for mut p in inputs.performers {
        let fallback = Fallback {
            on_lost: p.spec.on_lost.unwrap_or(config.on_lost),
            idle: p.idle.take(),
            resume: p.spec.resume_secs.map(std::time::Duration::from_secs_f64),
        };
        let (plan, tx) = performer_plan(p, &names, &subjects, config)?;
        subjects.push(plan.target.clone());
        plans.push(plan);
        target_txs.push((tx, fallback));
    }
    let subjects = Arc::new(subjects);
    let performers = plans
        .iter()
        .zip(target_txs)
        .map(|(plan, (tx, fallback))| performer(plan, tx, fallback, &subjects))
        .collect();
    let mapper = Mapper::new(
        subjects.clone(),
        plans,
        extras,
        config.mapping_cache_dir.clone(),
        config.rate_hz,
        events.clone(),
        inbox.clone(),
    );
    let mapper = first_mappings(mapper, config, inputs.cluster.as_ref()).await?;
    let vmc = vmc_output(config, &subjects).await?;
    Ok(Assembly {
        subjects,
        sources,
        performers,
        mapper,
        vmc,
        events,
        inbox,
        wake,
        token: inputs.token,
        cluster: inputs.cluster,
    })
}

/// One subject per source (ids in config order), and what the mapper may know of each
/// replay's motion.
fn source_runners(
    loaded: Vec<LoadedSource>,
    config: &ServerConfig,
) -> (Vec<SourceRunner>, HashMap<u32, SourceExtra>) {
    let mut runners = Vec::with_capacity(loaded.len());
    let mut extras = HashMap::new();
    for (i, source) in loaded.into_iter().enumerate() {
        let (runner, extra) = source_subject(i as u32, source, config);
        if let Some(extra) = extra {
            extras.insert(i as u32, extra);
        }
        runners.push(runner);
    }
    (runners, extras)
}

/// The engine's performer of `plan`, fed by its inputs' subjects, with what it does while
/// they are lost.
fn performer(
    plan: &PerformerPlan,
    tx: FrameWriter,
    fallback: Fallback,
    subjects: &[Arc<Subject>],
) -> Performer {
    let inputs = plan.target.inputs.iter();
    let performer = Performer::new(
        plan.target.clone(),
        tx,
        inputs.map(|id| subjects[*id as usize].clone()).collect(),
        Arc::default(),
        fallback.on_lost,
    );
    match (fallback.idle, fallback.resume) {
        (Some(idle), resume) => performer.with_idle_graph(idle, resume),
        (None, Some(resume)) => performer.with_resume(resume),
        (None, None) => performer,
    }
}

/// The mapper with its cache limit and, in cluster mode, the mappings shared between nodes,
/// once it has built every performer's first mapping (off the async threads).
async fn first_mappings(
    mapper: Mapper,
    config: &ServerConfig,
    cluster: Option<&crate::cluster::ClusterLink>,
) -> anyhow::Result<Mapper> {
    let mut mapper = mapper
        .with_max_cache_entries(config.limits.mapping_cache_max_entries)
        .with_shared(cluster.map(|link| {
            let c = &link.cluster;
            crate::cluster::SharedMappings::new(
                c.mappings.clone(),
                tokio::runtime::Handle::current(),
                c.mapping_counts.clone(),
            )
        }));
    let mapper = tokio::task::spawn_blocking(move || {
        mapper.build_all();
        mapper
    })
    .await?;
    Ok(mapper)
}

/// What a performer does while its source is lost, and how it comes back.
struct Fallback {
    on_lost: rigcast_engine::settings::OnLost,
    idle: Option<rigcast_engine::idle_graph::IdleGraph>,
    resume: Option<std::time::Duration>,
}

/// The subject of source `id`, and for a replay what the mapper may know of its motion.
fn source_subject(
    id: u32,
    source: LoadedSource,
    config: &ServerConfig,
) -> (SourceRunner, Option<SourceExtra>) {
    let LoadedSource {
        name,
        loaded,
        skeleton,
    } = source;
    let mut truth = None;
    let mut replay_poses = None;
    let mut extra = None;
    let (kind, listen, calibration) = match &loaded {
        Loaded::Replay {
            clip_poses,
            truth: t,
            ..
        } => {
            truth = t.clone();
            replay_poses = Some(clip_poses.clone());
            extra = Some(SourceExtra {
                reference: clip_poses.get(clip_poses.len() / 2).cloned(),
                poses: clip_poses.clone(),
            });
            (SourceKind::Replay, None, None)
        }
        Loaded::Live {
            kind,
            listen,
            calibration,
            ..
        } => (*kind, *listen, calibration.clone()),
    };
    let (subject, tx) = Subject::with_kind(
        id,
        name,
        skeleton,
        Some(kind),
        Vec::new(),
        config.vmc_bone_names,
    );
    let subject = subject
        .with_listen_addr(listen)
        .with_calibration(
            calibration
                .map(|h| Box::new(crate::calibration::SerialCalibration(h)) as Box<dyn Calibrator>),
        )
        .with_truth(truth);
    let subject = match &replay_poses {
        Some(poses) => subject.with_moving_bones(poses),
        None => subject,
    };
    let runner = SourceRunner {
        subject: Arc::new(subject),
        tx,
        loaded,
    };
    (runner, extra)
}

/// A performer's target subject (the next id after `subjects`) and its mapping plan.
fn performer_plan(
    p: LoadedPerformer,
    source_names: &[String],
    subjects: &[Arc<Subject>],
    config: &ServerConfig,
) -> anyhow::Result<(PerformerPlan, FrameWriter)> {
    let LoadedPerformer {
        spec,
        target: t,
        overrides_file,
        graft,
        idle: _,
    } = p;
    let inputs: Vec<u32> = if spec.sources.is_empty() {
        vec![0]
    } else {
        spec.sources
            .iter()
            .map(|n| {
                source_names
                    .iter()
                    .position(|m| m == n)
                    .map(|i| i as u32)
                    .with_context(|| no_source(&t.name, n, source_names, config))
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
    let name =
        rigcast_engine::subject_list::unique_name(&all_names, spec.name.clone().unwrap_or(t.name));
    let (subject, tx) = Subject::with_kind(
        subjects.len() as u32,
        name,
        t.skeleton,
        None,
        inputs,
        config.vmc_bone_names,
    );
    let plan = PerformerPlan {
        target: Arc::new(subject.with_truth(t.truth).with_model(t.model)),
        target_reference: t.reference,
        target_motion: t.motion,
        overrides_file,
        session: Default::default(),
        root_motion: if spec.in_place {
            RootMotion::InPlace
        } else {
            RootMotion::Scaled
        },
        foot_lock: spec.foot_lock,
        graft,
    };
    Ok((plan, tx))
}

/// Why performer `performer`'s source `name` is not there.
fn no_source(performer: &str, name: &str, sources: &[String], config: &ServerConfig) -> String {
    let hint = match (name.rsplit_once('@'), &config.cluster) {
        (Some(_), None) => " (NAME@SITE is another node's subject: run in cluster mode)",
        (Some((_, site)), Some(c)) if site == c.site => " (SITE is this node)",
        _ => "",
    };
    format!("performer {performer}: no source named {name:?}{hint} (sources: {sources:?})")
}

/// The VMC output socket and its receivers, resolved; `None` without receivers.
async fn vmc_output(
    config: &ServerConfig,
    subjects: &[Arc<Subject>],
) -> anyhow::Result<Option<(std::net::UdpSocket, Vec<VmcTarget>)>> {
    if config.vmc_out.is_empty() {
        return Ok(None);
    }
    let default_subject = subjects.iter().position(|s| s.is_target()).unwrap_or(0);
    let mut targets = Vec::new();
    for entry in &config.vmc_out {
        let addr = entry.address.as_str();
        let subject_index = match &entry.subject {
            Some(name) => subjects
                .iter()
                .position(|s| s.info().name == *name)
                .with_context(|| format!("VMC output {entry}: no subject named {name:?}"))?,
            None => default_subject,
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
    Ok(Some((socket, targets)))
}
