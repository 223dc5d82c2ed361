//! Start, step 1: open what the server reads — sources, characters, mapping files, the
//! control token. Everything here blocks (files, serial ports, ffmpeg, ONNX Runtime) and
//! runs on `spawn_blocking`, never on a runtime worker.

use std::net::SocketAddr;
use std::sync::Arc;

use anyhow::Context;
use rigcast_protocol::SourceKind;
use rigcast_retarget::mapping::{parse_mapping_file, MappingFile};
use rigcast_retarget::{Pose, Skeleton};
use rigcast_sources::live::LiveSource;
use rigcast_sources::serial::{CalibrationHandle, SerialImuConfig, SerialImuSource};
use rigcast_sources::vmc_in::{VmcConfig, VmcSource};
use rigcast_sources::{load_clip_and_humanoid, LoadOptions, LoadedClip, Replay, ReplayOptions};

use crate::config::{self, PerformerSpec, ReplaySettings, ServerConfig, SourceSpec, TargetSpec};
use crate::{character, demo, token};

/// A loaded source, before it becomes a subject.
pub(crate) enum Loaded {
    Replay {
        player: Replay,
        speed: f64,
        clip_poses: Arc<Vec<Pose>>,
        /// A VRM file's humanoid map (ground truth for its roles).
        truth: Option<Vec<(String, String)>>,
    },
    Live {
        source: Box<dyn LiveSource>,
        kind: SourceKind,
        listen: Option<SocketAddr>,
        /// Set for calibratable sources (serial IMU suits).
        calibration: Option<CalibrationHandle>,
    },
}

/// A source with its subject name and (initial) skeleton.
pub(crate) struct LoadedSource {
    pub name: String,
    pub loaded: Loaded,
    pub skeleton: Arc<Skeleton>,
}

/// A loaded character.
pub(crate) struct LoadedTarget {
    pub name: String,
    pub skeleton: Arc<Skeleton>,
    pub reference: Option<Pose>,
    /// A VRM file's humanoid map (ground truth for its roles).
    pub truth: Option<Vec<(String, String)>>,
    /// The character file the viewer may fetch (binary glTF targets only).
    pub model: Option<crate::model::ModelFile>,
}

/// A performer's spec with its character and mapping overrides read.
pub(crate) struct LoadedPerformer {
    pub spec: PerformerSpec,
    pub target: LoadedTarget,
    pub overrides_file: Option<MappingFile>,
    /// A grafted performer's lower body (its clip read when it is one).
    pub graft: Option<crate::graft_live::LowerInput>,
    /// The graph walked while its source is lost, prepared for the character.
    pub idle: Option<crate::idle_graph::IdleGraph>,
}

/// Everything the server reads at start.
pub(crate) struct Inputs {
    /// In config order; names are unique.
    pub sources: Vec<LoadedSource>,
    pub performers: Vec<LoadedPerformer>,
    pub token: token::ResolvedToken,
    /// Cluster mode: the connection and what feeds the other nodes' subjects (which follow
    /// this node's own in `sources`).
    pub cluster: Option<crate::cluster::ClusterLink>,
}

/// Opens every source, character, mapping file and the token of `config`. With no sources,
/// the embedded demo (and, with no performers either, the built-in mannequin driven by it).
pub(crate) async fn load(config: &ServerConfig) -> anyhow::Result<Inputs> {
    // Other nodes' subjects are known before the defaults are chosen: a node that relays
    // them needs no demo of its own.
    let (cluster, remote) = match &config.cluster {
        Some(c) => {
            let (link, remote) = crate::cluster::join(c, config.sources.len() as u32).await?;
            (Some(link), remote)
        }
        None => (None, Vec::new()),
    };
    let defaulted = config.sources.is_empty() && remote.is_empty();
    let specs = if defaulted {
        vec![SourceSpec::EmbeddedDemo]
    } else {
        config.sources.clone()
    };
    let mut performer_specs = config.performers.clone();
    if defaulted && performer_specs.is_empty() {
        // The default demo: the bundled walk and the built-in character retargeted from it.
        performer_specs.push(PerformerSpec::target_file(format!(
            "{}mannequin",
            config::BUILTIN_PREFIX
        )));
    }
    let mut sources: Vec<LoadedSource> = Vec::new();
    for spec in specs {
        let (name, loaded, skeleton) =
            tokio::task::spawn_blocking(move || load_source(spec)).await??;
        let taken: Vec<String> = sources.iter().map(|s| s.name.clone()).collect();
        sources.push(LoadedSource {
            name: unique_name(&taken, name),
            loaded,
            skeleton,
        });
    }
    for r in remote {
        let taken: Vec<String> = sources.iter().map(|s| s.name.clone()).collect();
        sources.push(LoadedSource {
            name: unique_name(&taken, r.name),
            loaded: Loaded::Live {
                source: Box::new(r.source),
                kind: SourceKind::Remote,
                listen: None,
                calibration: None,
            },
            skeleton: r.skeleton,
        });
    }
    let mut performers = Vec::new();
    for spec in performer_specs {
        let p = spec.clone();
        let target = tokio::task::spawn_blocking(move || load_target(&p)).await??;
        let overrides_file = match spec.mapping.clone() {
            Some(path) => Some(tokio::task::spawn_blocking(move || read_mapping(&path)).await??),
            None => None,
        };
        let graft = load_graft_lower(&spec).await?;
        let idle = load_idle_graph(&spec, &target, config.rate_hz).await?;
        performers.push(LoadedPerformer {
            spec,
            target,
            overrides_file,
            graft,
            idle,
        });
    }
    let token_setting = config.access.token.clone();
    let token = tokio::task::spawn_blocking(move || token_setting.resolve()).await??;
    Ok(Inputs {
        sources,
        performers,
        token,
        cluster,
    })
}

/// A performer's idle graph, read and prepared for its character (blocking work off the
/// runtime's workers).
async fn load_idle_graph(
    spec: &PerformerSpec,
    target: &LoadedTarget,
    rate_hz: f64,
) -> anyhow::Result<Option<crate::idle_graph::IdleGraph>> {
    let Some(path) = spec.idle_graph.clone() else {
        return Ok(None);
    };
    let skeleton = target.skeleton.clone();
    let reference = target.reference.clone();
    let tick_secs = (1.0 / rate_hz) as f32;
    let stay = spec.idle_clips.clone();
    let idle = tokio::task::spawn_blocking(move || {
        let reference = reference.as_ref();
        crate::idle_graph::IdleGraph::load(&path, &skeleton, reference, tick_secs, &stay)
    })
    .await??;
    Ok(Some(idle))
}

/// A performer's mapping overrides file.
fn read_mapping(path: &std::path::Path) -> anyhow::Result<MappingFile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the mapping file {}", path.display()))?;
    parse_mapping_file(&text).with_context(|| format!("mapping file {}", path.display()))
}

/// `name`, or `name-2`, `name-3`… when taken.
pub(crate) fn unique_name(taken: &[String], name: String) -> String {
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
/// A grafted performer's lower body: a source (resolved with the performer's inputs) or a
/// locomotion clip, read here.
async fn load_graft_lower(
    spec: &PerformerSpec,
) -> anyhow::Result<Option<crate::graft_live::LowerInput>> {
    use crate::graft_live::LowerInput;
    Ok(match spec.graft.as_ref().map(|g| &g.lower) {
        None => None,
        Some(config::LowerSpec::Source(_)) => Some(LowerInput::Source),
        Some(config::LowerSpec::Clip(path)) => {
            let path = path.clone();
            let clip = tokio::task::spawn_blocking(move || rigcast_sources::load_clip(&path))
                .await?
                .context("the graft's lower-body clip")?;
            Some(LowerInput::Clip(Arc::new(clip)))
        }
    })
}

fn load_target(p: &config::PerformerSpec) -> anyhow::Result<LoadedTarget> {
    match &p.target {
        TargetSpec::Skeleton { skeleton, name } => Ok(LoadedTarget {
            name: name.clone(),
            skeleton: skeleton.clone(),
            reference: None,
            truth: None,
            model: None,
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
                    model: None,
                });
            }
            let LoadedClip {
                clip,
                humanoid: truth,
            } = load_clip_and_humanoid(path, &LoadOptions::default())
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
                model: crate::model::ModelFile::for_target(path),
            })
        }
    }
}

/// A loaded source's subject name, what runs it and its (initial) skeleton.
type Opened = (String, Loaded, Arc<Skeleton>);

/// Loads a source: one arm per kind, each kind's opening in a function of its own. Blocks
/// (files, devices, model loading): call it from `spawn_blocking`.
fn load_source(spec: SourceSpec) -> anyhow::Result<Opened> {
    match spec {
        SourceSpec::ReplayFile {
            path,
            name,
            settings,
        } => open_replay_file(&path, name, settings),
        SourceSpec::ReplayClip {
            clip,
            name,
            settings,
        } => {
            let name = name.unwrap_or_else(|| clip.name.clone());
            replay_of(name, clip, settings, None)
        }
        SourceSpec::EmbeddedDemo => {
            replay_of("demo".into(), demo_clip()?, ReplaySettings::default(), None)
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
            open_vmc(cfg, name)
        }
        SourceSpec::Serial { config, name } => open_serial(&config, name),
        SourceSpec::Webcam { index, name } => {
            let (source, sk) = open_webcam(index)?;
            let name = name.unwrap_or_else(|| format!("webcam:{index}"));
            Ok((name, Loaded::live(source, SourceKind::Webcam), sk))
        }
        SourceSpec::Video { path, name } => {
            let (source, sk) = open_video(&path)?;
            let name = name.unwrap_or_else(|| stem(&path));
            Ok((name, Loaded::live(source, SourceKind::Video), sk))
        }
    }
}

impl Loaded {
    /// A live source that neither listens on a port nor calibrates.
    fn live(source: Box<dyn LiveSource>, kind: SourceKind) -> Loaded {
        Loaded::Live {
            source,
            kind,
            listen: None,
            calibration: None,
        }
    }
}

/// A clip played back as subject `name`.
fn replay_of(
    name: String,
    clip: rigcast_retarget::Clip,
    settings: ReplaySettings,
    truth: Option<Vec<(String, String)>>,
) -> anyhow::Result<Opened> {
    let skeleton = clip.skeleton.clone();
    let clip_poses = Arc::new(clip.poses.clone());
    let loaded = Loaded::Replay {
        player: replay(clip, settings)?,
        speed: settings.speed,
        clip_poses,
        truth,
    };
    Ok((name, loaded, skeleton))
}

/// A file (BVH, glTF/GLB/VRM, .rcr) played back; a VRM's humanoid map comes along.
fn open_replay_file(
    path: &std::path::Path,
    name: Option<String>,
    settings: ReplaySettings,
) -> anyhow::Result<Opened> {
    let LoadedClip {
        clip,
        humanoid: truth,
    } = load_clip_and_humanoid(path, &LoadOptions::default())
        .with_context(|| format!("cannot load source {}", path.display()))?;
    let name = name.unwrap_or_else(|| {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| clip.name.clone())
    });
    replay_of(name, clip, settings, truth)
}

/// VMC/OSC input on a UDP port.
fn open_vmc(cfg: VmcConfig, name: Option<String>) -> anyhow::Result<Opened> {
    let (bind, port) = (cfg.bind, cfg.port);
    let source = VmcSource::bind(cfg)
        .with_context(|| format!("cannot listen for VMC on UDP {bind} port {port}"))?;
    let listen = source.local_addr();
    let name = name.unwrap_or_else(|| format!("vmc:{}", listen.map(|a| a.port()).unwrap_or(port)));
    // Until the sender's own skeleton arrives, the standard humanoid stands in.
    let sk = match source.skeleton() {
        Some(s) => s,
        None => rigcast_sources::live::humanoid::default_humanoid()
            .context("building the default humanoid")?,
    };
    let loaded = Loaded::Live {
        source: Box::new(source),
        kind: SourceKind::Vmc,
        listen,
        calibration: None,
    };
    Ok((name, loaded, sk))
}

/// A serial IMU suit described by the TOML file `config`.
fn open_serial(config: &std::path::Path, name: Option<String>) -> anyhow::Result<Opened> {
    let text = std::fs::read_to_string(config)
        .with_context(|| format!("cannot read serial config {}", config.display()))?;
    let cfg = SerialImuConfig::from_toml(&text)
        .with_context(|| format!("serial config {}", config.display()))?;
    let humanoid = rigcast_sources::live::humanoid::default_humanoid()
        .context("building the default humanoid")?;
    let source = SerialImuSource::open(cfg, humanoid.clone())
        .with_context(|| format!("cannot open the serial suit of {}", config.display()))?;
    let sk = source.skeleton().unwrap_or(humanoid);
    let name = name.unwrap_or_else(|| stem(config));
    let calibration = Some(source.calibration_handle());
    let loaded = Loaded::Live {
        source: Box::new(source),
        kind: SourceKind::Serial,
        listen: None,
        calibration,
    };
    Ok((name, loaded, sk))
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
    use rigcast_sources::vision::{
        ffmpeg::DEFAULT_SEQUENCE_FPS, DecodeSize, FfmpegSource, PipelineConfig, PosePipeline,
        VisionSource,
    };
    let frames = FfmpegSource::open_at(path, DecodeSize::FOR_MODEL, DEFAULT_SEQUENCE_FPS)
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
            tracing::warn!("bundled demo unavailable ({e}); using the procedural demo");
            Ok(demo::procedural_clip(120, 30.0)?)
        }
    }
}
