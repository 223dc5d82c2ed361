//! Start, step 1: open what the server reads — sources, characters, mapping files, the
//! control token. Everything here blocks (files, serial ports, ffmpeg, ONNX Runtime) and
//! runs on `spawn_blocking`, never on a runtime worker.

use std::sync::Arc;

use anyhow::Context;
use rigcast_protocol::SourceKind;
use rigcast_retarget::mapping::{parse_mapping_file, MappingFile};
use rigcast_retarget::{Pose, Skeleton};

use crate::config::{self, PerformerSpec, ServerConfig, SourceSpec, TargetSpec};
use crate::model::ServedModel;
pub(crate) use crate::source_kinds::Loaded;
use crate::source_kinds::Opened;
use crate::{character, token};
use rigcast_engine::subject_list::unique_name;

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
    /// The character file's own animation (empty without one): motion evidence for its mapping.
    pub motion: Arc<[Pose]>,
    /// A VRM file's humanoid map (ground truth for its roles).
    pub truth: Option<Vec<(String, String)>>,
    /// The character file the viewer may fetch (binary glTF targets only).
    pub model: Option<rigcast_engine::subject::ModelFile>,
}

/// A performer's spec with its character and mapping overrides read.
pub(crate) struct LoadedPerformer {
    pub spec: PerformerSpec,
    pub target: LoadedTarget,
    pub overrides_file: Option<MappingFile>,
    /// A grafted performer's lower body (its clip read when it is one).
    pub graft: Option<rigcast_engine::graft_live::LowerInput>,
    /// The graph walked while its source is lost, prepared for the character.
    pub idle: Option<rigcast_engine::idle_graph::IdleGraph>,
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
    let (cluster, remote) = join_cluster(config).await?;
    let defaulted = config.sources.is_empty() && remote.is_empty();
    let (specs, performer_specs) = with_defaults(config, defaulted);
    let sources = load_sources(specs, remote).await?;
    let mut performers = Vec::new();
    for spec in performer_specs {
        performers.push(load_performer(spec, config.rate_hz).await?);
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

/// Joins the cluster, if configured: the link and the other nodes' subjects. Those the
/// performers name are made even when their node has not published them yet, so the
/// performers wait for them instead of failing.
async fn join_cluster(
    config: &ServerConfig,
) -> anyhow::Result<(
    Option<crate::cluster::ClusterLink>,
    Vec<crate::cluster::RemoteSubject>,
)> {
    let Some(c) = &config.cluster else {
        return Ok((None, Vec::new()));
    };
    let wanted: Vec<String> = (config.performers.iter())
        .flat_map(|p| p.sources.iter().cloned())
        .collect();
    let first_id = config.sources.len() as u32;
    let (link, remote) = crate::cluster::join(c, first_id, &wanted).await?;
    Ok((Some(link), remote))
}

/// The sources and performers to load: the configured ones, or (`defaulted`: no sources here
/// or elsewhere) the embedded demo, and with no performers either the built-in mannequin.
fn with_defaults(config: &ServerConfig, defaulted: bool) -> (Vec<SourceSpec>, Vec<PerformerSpec>) {
    let specs = if defaulted {
        vec![SourceSpec::demo()]
    } else {
        config.sources.clone()
    };
    let mut performer_specs = config.performers.clone();
    if defaulted && performer_specs.is_empty() {
        // The default demo: the bundled walk and the built-in character retargeted from it.
        performer_specs.push(PerformerSpec::target_file(format!(
            "{}mannequin",
            rigcast_engine::builtin::BUILTIN_PREFIX
        )));
    }
    (specs, performer_specs)
}

/// Opens every configured source (blocking work off the runtime's workers), then adds the
/// other nodes' subjects; each gets a name no earlier one has.
async fn load_sources(
    specs: Vec<SourceSpec>,
    remote: Vec<crate::cluster::RemoteSubject>,
) -> anyhow::Result<Vec<LoadedSource>> {
    let mut sources: Vec<LoadedSource> = Vec::new();
    // Subjects of one video or camera share its pipeline.
    let vision = crate::source_kinds::VisionInputs::default();
    for spec in specs {
        let vision = vision.clone();
        let (name, loaded, skeleton) =
            tokio::task::spawn_blocking(move || load_source(spec, &vision)).await??;
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
    Ok(sources)
}

/// One performer's character, mapping file, graft and idle graph.
async fn load_performer(spec: PerformerSpec, rate_hz: f64) -> anyhow::Result<LoadedPerformer> {
    let p = spec.clone();
    let target = tokio::task::spawn_blocking(move || load_target(&p)).await??;
    let overrides_file = match spec.mapping.clone() {
        Some(path) => Some(tokio::task::spawn_blocking(move || read_mapping(&path)).await??),
        None => None,
    };
    let graft = load_graft_lower(&spec).await?;
    let idle = load_idle_graph(&spec, &target, rate_hz).await?;
    Ok(LoadedPerformer {
        spec,
        target,
        overrides_file,
        graft,
        idle,
    })
}

/// A performer's idle graph, read and prepared for its character (blocking work off the
/// runtime's workers).
async fn load_idle_graph(
    spec: &PerformerSpec,
    target: &LoadedTarget,
    rate_hz: f64,
) -> anyhow::Result<Option<rigcast_engine::idle_graph::IdleGraph>> {
    let Some(path) = spec.idle_graph.clone() else {
        return Ok(None);
    };
    let skeleton = target.skeleton.clone();
    let reference = target.reference.clone();
    let tick_secs = (1.0 / rate_hz) as f32;
    let stay = spec.idle_clips.clone();
    let idle = tokio::task::spawn_blocking(move || {
        let reference = reference.as_ref();
        crate::idle_graph::load(&path, &skeleton, reference, tick_secs, &stay)
    })
    .await??;
    Ok(Some(idle))
}

/// A mapping overrides file (a performer's, or `rigcast retarget --mapping`).
pub(crate) fn read_mapping(path: &std::path::Path) -> anyhow::Result<MappingFile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the mapping file {}", path.display()))?;
    parse_mapping_file(&text).with_context(|| format!("mapping file {}", path.display()))
}

/// Loads a character: a file (its animation only serves as a reference posture) or a
/// built-in.
/// A grafted performer's lower body: a source (resolved with the performer's inputs) or a
/// locomotion clip, read here.
async fn load_graft_lower(
    spec: &PerformerSpec,
) -> anyhow::Result<Option<rigcast_engine::graft_live::LowerInput>> {
    use rigcast_engine::graft_live::LowerInput;
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
            motion: Arc::from(Vec::new()),
            truth: None,
            model: None,
        }),
        TargetSpec::File(path) => {
            let c = match character::load_character(path) {
                Ok(c) => c,
                Err(e @ character::CharacterError::UnknownBuiltin { .. }) => return Err(e.into()),
                Err(e) => {
                    return Err(anyhow::Error::new(e)
                        .context(format!("cannot load target character {}", path.display())))
                }
            };
            let clip = c.clip;
            Ok(LoadedTarget {
                name: c.name,
                reference: clip.poses.get(clip.poses.len() / 2).cloned(),
                motion: Arc::from(clip.poses.clone()),
                skeleton: clip.skeleton,
                truth: c.truth,
                model: c
                    .file
                    .as_deref()
                    .and_then(rigcast_engine::subject::ModelFile::for_target),
            })
        }
    }
}

/// Loads a source (one arm per kind, in `source_kinds`; video and webcam subjects of one
/// input share `vision`). Blocks (files, devices, model loading): call it from
/// `spawn_blocking`.
fn load_source(
    spec: SourceSpec,
    vision: &crate::source_kinds::VisionInputs,
) -> anyhow::Result<Opened> {
    spec.open_with(vision)
}
