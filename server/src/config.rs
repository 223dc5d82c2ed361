//! Server configuration: the `rigcast.toml` file format and the resolved [`ServerConfig`].
//!
//! ```toml
//! listen = "127.0.0.1:8717"
//! rate_hz = 60
//! vmc_out = ["127.0.0.1:39539"]
//!
//! [[sources]]
//! kind = "replay"
//! path = "recordings/demo.rcr"
//! speed = 1.0
//! loop = true
//! start_offset_secs = 0.0
//! name = "demo"
//! ```
//!
//! Command-line flags override file values; see `cmd::serve`.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use std::str::FromStr;

use serde::Deserialize;

pub use crate::cluster_config::ClusterConfig;
pub use crate::config_error::ConfigError;
pub use crate::source_kinds::{
    DemoSpec, ReplayClipSpec, ReplayFileSpec, ReplaySettings, SerialSpec, SourceSpec, VideoSpec,
    VmcSpec, WebcamSpec, DEFAULT_VMC_BIND,
};
pub use crate::token::TokenSetting;
use rigcast_engine::builtin::BUILTIN_PREFIX;
use rigcast_engine::settings::{OnLost, VmcBoneNames};

/// Default listen address: loopback only (nothing is exposed to the network unless asked) on
/// port 8717 (unassigned by IANA, mnemonic: "RiGcast" is not a number, so we simply picked one
/// next to the common 8xxx development ports without colliding with 8080/8000/8888).
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8717";
/// Default output rate.
pub const DEFAULT_RATE_HZ: f64 = 60.0;
/// Accepted output rates.
pub const RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 1.0..=240.0;

/// `rigcast.toml` as written by users. Every field is optional.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileConfig {
    /// Listen address, e.g. `"127.0.0.1:8717"`.
    pub listen: Option<String>,
    /// Output tick rate in Hz (1..=240).
    pub rate_hz: Option<f64>,
    /// Pose sources.
    #[serde(default)]
    pub sources: Vec<SourceSpec>,
    /// VMC receivers: `"host:port"` or `{ address = "host:port", subject = "name" }`.
    #[serde(default)]
    pub vmc_out: Vec<VmcOut>,
    /// Bone names sent over VMC: `"humanoid"` (default) or `"skeleton"`.
    pub vmc_bone_names: Option<VmcBoneNames>,
    /// Retargeted characters.
    #[serde(default)]
    pub performers: Vec<FilePerformer>,
    /// Default behaviour of targets whose source is lost: `"ease"` (default) or `"hold"`.
    pub on_lost: Option<OnLost>,
    /// Record every subject and the raw input of live sources into this `.rcr` file.
    pub record: Option<PathBuf>,
    /// Mapping cache: `true` (default folder), `false`, or a folder.
    pub mapping_cache: Option<FileMappingCache>,
    /// Most mapping tables kept in the cache, in memory and on disk each (default 128).
    pub mapping_cache_max_entries: Option<usize>,
    /// Web page origins (`scheme://host[:port]`) allowed besides the served viewer.
    #[serde(default)]
    pub allowed_origins: Vec<String>,
    /// Host names (optionally `name:port`) accepted in the `Host` header besides localhost
    /// and IP addresses.
    #[serde(default)]
    pub allowed_hosts: Vec<String>,
    /// The control token's file (default `$XDG_CONFIG_HOME/rigcast/token`).
    pub token_file: Option<PathBuf>,
    /// Most simultaneous connections (default: the open-file limit minus 64).
    pub max_connections: Option<usize>,
    /// A client whose socket accepts nothing for this long is disconnected (default 10 s).
    pub stalled_client_timeout_secs: Option<f64>,
    /// Cluster mode: share subjects with other nodes over NATS.
    pub cluster: Option<ClusterConfig>,
}

/// A VMC receiver and the subject it receives: `vmc_out = ["host:port", { address =
/// "host:port", subject = "name" }]` in the file, `--vmc-out host:port[@subject]` on the
/// command line ([`FromStr`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VmcOut {
    /// `host:port`, resolved at start.
    pub address: String,
    /// Subject name (`None`: the first target, else the first source).
    pub subject: Option<String>,
}

impl VmcOut {
    /// The default subject sent to `address`.
    pub fn to(address: impl Into<String>) -> VmcOut {
        VmcOut {
            address: address.into(),
            subject: None,
        }
    }
}

impl FromStr for VmcOut {
    type Err = std::convert::Infallible;

    /// `host:port` or `host:port@subject`.
    fn from_str(s: &str) -> Result<VmcOut, Self::Err> {
        Ok(match s.rsplit_once('@') {
            Some((address, subject)) => VmcOut {
                address: address.into(),
                subject: Some(subject.into()),
            },
            None => VmcOut::to(s),
        })
    }
}

impl std::fmt::Display for VmcOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.subject {
            Some(subject) => write!(f, "{}@{subject}", self.address),
            None => f.write_str(&self.address),
        }
    }
}

/// The table spelling of a `vmc_out` entry.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct VmcOutTable {
    address: String,
    subject: Option<String>,
}

/// `"host:port"` or a table; by hand rather than `untagged`, so that a wrong key in the table
/// is reported by name.
impl<'de> Deserialize<'de> for VmcOut {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<VmcOut, D::Error> {
        struct Spellings;
        impl<'de> serde::de::Visitor<'de> for Spellings {
            type Value = VmcOut;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"host:port\" or { address = \"host:port\", subject = \"name\" }")
            }

            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<VmcOut, E> {
                Ok(VmcOut::to(v))
            }

            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<VmcOut, A::Error> {
                let t =
                    VmcOutTable::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(VmcOut {
                    address: t.address,
                    subject: t.subject,
                })
            }
        }
        d.deserialize_any(Spellings)
    }
}

/// `mapping_cache = true | false | "folder"`.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum FileMappingCache {
    /// On (default folder) or off.
    Enabled(bool),
    /// This folder.
    Folder(PathBuf),
}

/// Sources of a performer: one name or a list (many-to-one).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum FileNames {
    /// One source subject.
    One(String),
    /// Several source subjects blended onto one target.
    Many(Vec<String>),
}

/// One `[[performers]]` entry: a character driven by source subject(s).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilePerformer {
    /// Source subject name(s) (default: the first source).
    pub source: Option<FileNames>,
    /// The character file (BVH, glTF/GLB, VRM, .rcr; its animation is ignored), or
    /// `"builtin:mannequin"`.
    pub target: PathBuf,
    /// Subject name of the retargeted character (default: the file stem).
    pub name: Option<String>,
    /// Mapping overrides (TOML, see retarget/MAPPING.md).
    pub mapping: Option<PathBuf>,
    /// Keep the hips over the spot horizontally.
    #[serde(default)]
    pub in_place: bool,
    /// What the character does while its source is lost.
    pub on_lost: Option<OnLost>,
    /// A motion graph (`.rmg`, from `rigcast graph build`) the character walks on while its
    /// source is lost; implies `on_lost = "idle"`.
    pub idle_graph: Option<PathBuf>,
    /// The clips of `idle_graph` (names or numbers) the walk may switch into, e.g. only the
    /// idle ones of a graph that also holds walks (default: all).
    pub idle_clips: Option<Vec<String>>,
    /// Seconds to blend back to live motion when the source returns (default 0.3 with an
    /// idle graph, else 0.2).
    pub resume_secs: Option<f64>,
    /// Pin the character's feet while the source's are planted (default: on for humanoid and
    /// quadruped characters).
    pub foot_lock: Option<bool>,
    /// A graft: the source subject whose upper body (spine above the waist, arms, head) drives
    /// the character; with `lower`, instead of `source`.
    pub upper: Option<String>,
    /// A graft's lower body (pelvis, legs): a source subject, or a locomotion clip file
    /// (`.bvh`, `.glb`, `.gltf`, `.vrm`, `.rcr`) looped in step, its footplants locked.
    pub lower: Option<String>,
}

/// File extensions that make a performer's `lower` a locomotion clip rather than a subject.
pub const CLIP_EXTENSIONS: [&str; 5] = ["bvh", "glb", "gltf", "vrm", "rcr"];

/// Whether `lower` names a clip file (by its extension) rather than a source subject.
pub fn is_clip_path(lower: &str) -> bool {
    Path::new(lower)
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| CLIP_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Where a grafted performer's lower body comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum LowerSpec {
    /// A source subject (the performer's second input).
    Source(String),
    /// A locomotion clip, looped one stride at a time.
    Clip(PathBuf),
}

/// A performer grafted from two inputs (see `graft_live`).
#[derive(Debug, Clone, PartialEq)]
pub struct GraftSpec {
    /// The source subject whose upper body drives the character.
    pub upper: String,
    /// The lower body's input.
    pub lower: LowerSpec,
}

impl FileConfig {
    /// Reads and parses a config file; relative source paths are resolved against its folder.
    pub fn load(path: &Path) -> Result<FileConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let mut cfg: FileConfig = toml::from_str(&text).map_err(|source| ConfigError::Parse {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        let resolve = |p: &mut PathBuf| {
            if p.is_relative() && !p.to_string_lossy().starts_with(BUILTIN_PREFIX) {
                *p = base.join(&*p);
            }
        };
        for s in &mut cfg.sources {
            if let Some(path) = s.file_mut() {
                resolve(path);
            }
        }
        for p in &mut cfg.performers {
            resolve(&mut p.target);
            if let Some(lower) = p.lower.as_mut().filter(|l| is_clip_path(l)) {
                let mut path = PathBuf::from(&*lower);
                resolve(&mut path);
                *lower = path.to_string_lossy().into_owned();
            }
            if let Some(m) = p.mapping.as_mut() {
                resolve(m);
            }
        }
        if let Some(r) = cfg.record.as_mut() {
            resolve(r);
        }
        if let Some(FileMappingCache::Folder(f)) = cfg.mapping_cache.as_mut() {
            resolve(f);
        }
        if let Some(t) = cfg.token_file.as_mut() {
            resolve(t);
        }
        Ok(cfg)
    }
}

/// Who may use the HTTP listener (see [`crate::access`]).
#[derive(Debug, Clone, PartialEq)]
pub struct AccessConfig {
    /// Web page origins allowed besides the served viewer.
    pub allowed_origins: Vec<String>,
    /// `Host` names allowed besides localhost and IP addresses.
    pub allowed_hosts: Vec<String>,
    /// Where the control token comes from.
    pub token: TokenSetting,
}

impl Default for AccessConfig {
    fn default() -> Self {
        AccessConfig {
            allowed_origins: Vec::new(),
            allowed_hosts: Vec::new(),
            token: TokenSetting::Ephemeral,
        }
    }
}

/// Longest timeout a config may set (a day): far beyond any use, and a `Duration` for sure.
pub const MAX_TIMEOUT_SECS: f64 = 86_400.0;

/// Default for [`LimitsConfig::stalled_client_timeout_secs`].
pub const DEFAULT_STALLED_CLIENT_TIMEOUT_SECS: f64 = 10.0;

/// Resource bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitsConfig {
    /// Most simultaneous connections (`None`: the open-file limit minus a reserve).
    pub max_connections: Option<usize>,
    /// A client whose socket takes nothing for this long is disconnected.
    pub stalled_client_timeout_secs: f64,
    /// Most mapping tables cached (memory and disk each).
    pub mapping_cache_max_entries: usize,
}

impl Default for LimitsConfig {
    fn default() -> Self {
        LimitsConfig {
            max_connections: None,
            stalled_client_timeout_secs: DEFAULT_STALLED_CLIENT_TIMEOUT_SECS,
            mapping_cache_max_entries: crate::mapping_store::DEFAULT_MAX_ENTRIES,
        }
    }
}

/// The character a performer drives.
#[derive(Debug, Clone)]
pub enum TargetSpec {
    /// A character file, or `builtin:NAME`.
    File(PathBuf),
    /// A skeleton already in memory (tests, generated content).
    Skeleton {
        /// The skeleton.
        skeleton: std::sync::Arc<rigcast_retarget::Skeleton>,
        /// Subject name.
        name: String,
    },
}

/// A performer: source subject(s) driving a target character through a mapping.
#[derive(Debug, Clone)]
pub struct PerformerSpec {
    /// Source subject names (empty = the first source).
    pub sources: Vec<String>,
    /// The character.
    pub target: TargetSpec,
    /// Subject name (default: the file stem).
    pub name: Option<String>,
    /// Mapping overrides file.
    pub mapping: Option<PathBuf>,
    /// Walk on the spot.
    pub in_place: bool,
    /// Behaviour while the source is lost (default: the server's `on_lost`).
    pub on_lost: Option<OnLost>,
    /// The motion graph walked while the source is lost (with [`OnLost::Idle`]).
    pub idle_graph: Option<PathBuf>,
    /// The clips of the idle graph its walk may switch into (empty: all).
    pub idle_clips: Vec<String>,
    /// Blend back to live over this many seconds when the source returns (`None`: 0.3 s
    /// after an idle graph, 0.2 s otherwise).
    pub resume_secs: Option<f64>,
    /// Foot locking (`None`: on for humanoid and quadruped characters).
    pub foot_lock: Option<bool>,
    /// Upper and lower body from two inputs (`sources` then lists the upper source, and the
    /// lower one when it is a source).
    pub graft: Option<GraftSpec>,
}

impl PerformerSpec {
    /// The character in `path` driven by the first source.
    pub fn target_file(path: impl Into<PathBuf>) -> PerformerSpec {
        PerformerSpec {
            sources: Vec::new(),
            target: TargetSpec::File(path.into()),
            name: None,
            mapping: None,
            in_place: false,
            on_lost: None,
            idle_graph: None,
            idle_clips: Vec::new(),
            resume_secs: None,
            foot_lock: None,
            graft: None,
        }
    }
}

/// A `[[performers]]` entry as the server runs it: `upper` + `lower` make a graft, whose
/// inputs are the upper source and (unless the lower body is a clip) the lower one.
fn performer_spec(p: FilePerformer) -> Result<PerformerSpec, ConfigError> {
    let graft = match (p.upper, p.lower, &p.source) {
        (None, None, _) => None,
        (Some(upper), Some(lower), None) => Some(GraftSpec {
            upper,
            lower: if is_clip_path(&lower) {
                LowerSpec::Clip(PathBuf::from(lower))
            } else {
                LowerSpec::Source(lower)
            },
        }),
        (_, _, Some(_)) => {
            return Err(ConfigError::Invalid {
                field: "performers.upper / performers.lower",
                message: "a grafted performer takes `upper` and `lower` instead of `source`".into(),
            })
        }
        _ => {
            return Err(ConfigError::Invalid {
                field: "performers.upper / performers.lower",
                message: "a graft needs both `upper` (a source) and `lower` (a source or a clip)"
                    .into(),
            })
        }
    };
    let sources = match (&graft, p.source) {
        (Some(g), _) => match &g.lower {
            LowerSpec::Source(l) => vec![g.upper.clone(), l.clone()],
            LowerSpec::Clip(_) => vec![g.upper.clone()],
        },
        (None, None) => Vec::new(),
        (None, Some(FileNames::One(s))) => vec![s],
        (None, Some(FileNames::Many(v))) => v,
    };
    let on_lost = match (p.on_lost, &p.idle_graph) {
        (None, Some(_)) => Some(OnLost::Idle),
        (Some(OnLost::Ease | OnLost::Hold), Some(_)) => {
            return Err(ConfigError::Invalid {
                field: "performers.idle_graph",
                message: "an idle graph is walked with on_lost = \"idle\" (or no on_lost)".into(),
            })
        }
        (o, _) => o,
    };
    Ok(PerformerSpec {
        sources,
        target: TargetSpec::File(p.target),
        name: p.name,
        mapping: p.mapping,
        in_place: p.in_place,
        on_lost,
        idle_graph: p.idle_graph,
        idle_clips: p.idle_clips.unwrap_or_default(),
        resume_secs: p.resume_secs,
        foot_lock: p.foot_lock,
        graft,
    })
}

/// Fully resolved server settings.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// Address for HTTP + WebSocket; port 0 picks a free port.
    pub listen: SocketAddr,
    /// Output tick rate, Hz.
    pub rate_hz: f64,
    /// Subjects to stream (empty = the embedded demo).
    pub sources: Vec<SourceSpec>,
    /// VMC receivers (resolved at start).
    pub vmc_out: Vec<VmcOut>,
    /// Retargeted characters. With no sources and no performers the server streams the
    /// bundled demo and the built-in mannequin retargeted from it.
    pub performers: Vec<PerformerSpec>,
    /// Default behaviour of targets whose source is lost.
    pub on_lost: OnLost,
    /// Bone names sent over VMC.
    pub vmc_bone_names: VmcBoneNames,
    /// Record every subject (and raw live input) into this `.rcr` file.
    pub record: Option<PathBuf>,
    /// Folder of the on-disk mapping cache (`None`: memory only).
    pub mapping_cache_dir: Option<PathBuf>,
    /// Origin/Host checks and the control token.
    pub access: AccessConfig,
    /// Connection, client and cache bounds.
    pub limits: LimitsConfig,
    /// Cluster mode (NATS), off when `None`.
    pub cluster: Option<ClusterConfig>,
}

/// The default on-disk mapping cache: `$XDG_CACHE_HOME/rigcast/mappings`, else
/// `~/.cache/rigcast/mappings`.
pub fn default_mapping_cache_dir() -> Option<PathBuf> {
    crate::dirs::rigcast_dir(crate::dirs::UserBase::Cache, "mappings")
}

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig {
            listen: SocketAddr::from(([127, 0, 0, 1], 8717)),
            rate_hz: DEFAULT_RATE_HZ,
            sources: Vec::new(),
            vmc_out: Vec::new(),
            performers: Vec::new(),
            on_lost: OnLost::default(),
            vmc_bone_names: VmcBoneNames::default(),
            record: None,
            mapping_cache_dir: None,
            access: AccessConfig::default(),
            limits: LimitsConfig::default(),
            cluster: None,
        }
    }
}

impl ServerConfig {
    /// Checks ranges (rate, replay speeds) and that every idling performer has a graph.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_performers()?;
        let stall = self.limits.stalled_client_timeout_secs;
        // Bounded above too: a timeout of 1e300 s is finite but no `Duration`.
        if !(stall.is_finite() && stall > 0.0 && stall <= MAX_TIMEOUT_SECS) {
            return Err(ConfigError::Invalid {
                field: "stalled_client_timeout_secs",
                message: format!(
                    "{stall:?} must be a positive number of seconds up to {MAX_TIMEOUT_SECS}"
                ),
            });
        }
        if self.limits.max_connections == Some(0) || self.limits.mapping_cache_max_entries == 0 {
            return Err(ConfigError::Invalid {
                field: "max_connections / mapping_cache_max_entries",
                message: "must be at least 1".into(),
            });
        }
        if !RATE_RANGE_HZ.contains(&self.rate_hz) {
            return Err(ConfigError::Invalid {
                field: "rate_hz",
                message: format!("{:?} is outside 1..=240", self.rate_hz),
            });
        }
        for s in &self.sources {
            s.validate()?;
        }
        if let Some(cluster) = &self.cluster {
            cluster.validate()?;
        }
        Ok(())
    }

    /// An idle fallback needs its graph; a resume time is a positive number of seconds.
    fn validate_performers(&self) -> Result<(), ConfigError> {
        for p in &self.performers {
            let idle = p.on_lost.unwrap_or(self.on_lost) == OnLost::Idle;
            if idle && p.idle_graph.is_none() {
                return Err(ConfigError::Invalid {
                    field: "on_lost",
                    message: "\"idle\" needs the performer's idle_graph (a .rmg file)".into(),
                });
            }
            if !p.idle_clips.is_empty() && p.idle_graph.is_none() {
                return Err(ConfigError::Invalid {
                    field: "performers.idle_clips",
                    message: "names clips of the performer's idle_graph, which it has not".into(),
                });
            }
            if let Some(r) = p.resume_secs {
                if !(r.is_finite() && (0.0..=10.0).contains(&r)) {
                    return Err(ConfigError::Invalid {
                        field: "performers.resume_secs",
                        message: format!("{r:?} must be between 0 and 10 seconds"),
                    });
                }
            }
        }
        Ok(())
    }

    /// Applies a parsed file on top of the defaults.
    pub fn from_file(file: FileConfig) -> Result<ServerConfig, ConfigError> {
        let mut cfg = ServerConfig::default();
        if let Some(listen) = file.listen {
            cfg.listen = parse_listen(&listen)?;
        }
        if let Some(rate) = file.rate_hz {
            cfg.rate_hz = rate;
        }
        cfg.vmc_out = file.vmc_out;
        cfg.vmc_bone_names = file.vmc_bone_names.unwrap_or_default();
        cfg.on_lost = file.on_lost.unwrap_or_default();
        cfg.record = file.record;
        cfg.mapping_cache_dir = match file.mapping_cache {
            None | Some(FileMappingCache::Enabled(true)) => default_mapping_cache_dir(),
            Some(FileMappingCache::Enabled(false)) => None,
            Some(FileMappingCache::Folder(f)) => Some(f),
        };
        cfg.access = AccessConfig {
            allowed_origins: file.allowed_origins,
            allowed_hosts: file.allowed_hosts,
            token: file
                .token_file
                .or_else(crate::token::default_token_path)
                .map(TokenSetting::File)
                .unwrap_or(TokenSetting::Ephemeral),
        };
        cfg.cluster = file.cluster.clone();
        cfg.limits = LimitsConfig {
            max_connections: file.max_connections,
            stalled_client_timeout_secs: file
                .stalled_client_timeout_secs
                .unwrap_or(DEFAULT_STALLED_CLIENT_TIMEOUT_SECS),
            mapping_cache_max_entries: file
                .mapping_cache_max_entries
                .unwrap_or(crate::mapping_store::DEFAULT_MAX_ENTRIES),
        };
        cfg.performers = file
            .performers
            .into_iter()
            .map(performer_spec)
            .collect::<Result<_, _>>()?;
        cfg.sources = file.sources;
        cfg.validate()?;
        Ok(cfg)
    }
}

/// Parses a listen address (`ip:port`).
pub fn parse_listen(s: &str) -> Result<SocketAddr, ConfigError> {
    s.parse().map_err(|e| ConfigError::Invalid {
        field: "listen",
        message: format!("{s:?} is not an ip:port address ({e})"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_protocol::SourceKind;
    use std::net::IpAddr;

    #[test]
    fn parses_documented_example() {
        let text = r#"
            listen = "0.0.0.0:9000"
            rate_hz = 120
            vmc_out = ["127.0.0.1:39539"]
            [[sources]]
            kind = "replay"
            path = "/x/walk.bvh"
            speed = 0.5
            loop = false
            name = "walker"
        "#;
        let file: FileConfig = toml::from_str(text).unwrap();
        let cfg = ServerConfig::from_file(file).unwrap();
        assert_eq!(cfg.listen.port(), 9000);
        assert_eq!(cfg.rate_hz, 120.0);
        assert_eq!(cfg.vmc_out, vec![VmcOut::to("127.0.0.1:39539")]);
        match &cfg.sources[0] {
            SourceSpec::ReplayFile(crate::config::ReplayFileSpec {
                path,
                name,
                settings,
            }) => {
                assert_eq!(path, Path::new("/x/walk.bvh"));
                assert_eq!(name.as_deref(), Some("walker"));
                assert_eq!(settings.speed, 0.5);
                assert!(!settings.looping);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn load_resolves_relative_paths_against_the_file() {
        let dir = std::env::temp_dir().join(format!("rigcast-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rigcast.toml");
        std::fs::write(
            &path,
            "[[sources]]\nkind = \"replay\"\npath = \"clips/a.bvh\"\n",
        )
        .unwrap();
        let cfg = ServerConfig::from_file(FileConfig::load(&path).unwrap()).unwrap();
        match &cfg.sources[0] {
            SourceSpec::ReplayFile(crate::config::ReplayFileSpec { path, settings, .. }) => {
                assert_eq!(path, &dir.join("clips/a.bvh"));
                assert_eq!(*settings, ReplaySettings::default());
            }
            other => panic!("{other:?}"),
        }
        std::fs::write(&path, "rate_hz = \"fast\"\n").unwrap();
        let err = FileConfig::load(&path).unwrap_err().to_string();
        assert!(
            err.contains("rigcast.toml") && err.contains("line 1"),
            "{err}"
        );
        assert!(FileConfig::load(&dir.join("missing.toml")).is_err());
    }

    #[test]
    fn grafted_performers_take_upper_and_lower() {
        let dir = std::env::temp_dir().join(format!("rigcast-graftcfg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rigcast.toml");
        let text = r#"
            [[performers]]
            target = "builtin:mannequin"
            upper = "webcam"
            lower = "walks/walk.bvh"
            [[performers]]
            target = "builtin:mannequin"
            upper = "webcam"
            lower = "suit"
        "#;
        std::fs::write(&path, text).unwrap();
        let cfg = ServerConfig::from_file(FileConfig::load(&path).unwrap()).unwrap();
        let (a, b) = (&cfg.performers[0], &cfg.performers[1]);
        assert_eq!(a.sources, vec!["webcam".to_string()]);
        assert_eq!(
            a.graft,
            Some(GraftSpec {
                upper: "webcam".into(),
                lower: LowerSpec::Clip(dir.join("walks/walk.bvh")),
            })
        );
        assert_eq!(b.sources, vec!["webcam".to_string(), "suit".to_string()]);
        assert_eq!(
            b.graft.as_ref().unwrap().lower,
            LowerSpec::Source("suit".into())
        );
        for (bad, want) in [
            ("upper = \"webcam\"", "needs both"),
            ("lower = \"walk.bvh\"", "needs both"),
            (
                "source = \"x\"\nupper = \"a\"\nlower = \"b\"",
                "instead of `source`",
            ),
        ] {
            let text = format!("[[performers]]\ntarget = \"builtin:mannequin\"\n{bad}\n");
            let file: FileConfig = toml::from_str(&text).unwrap();
            let err = ServerConfig::from_file(file).unwrap_err().to_string();
            assert!(err.contains(want), "{bad}: {err}");
        }
    }

    #[test]
    fn example_file_parses() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("rigcast.example.toml");
        let cfg = ServerConfig::from_file(FileConfig::load(&path).unwrap()).unwrap();
        assert_eq!(cfg.listen, parse_listen(DEFAULT_LISTEN).unwrap());
        assert_eq!(cfg.rate_hz, DEFAULT_RATE_HZ);
        assert_eq!(cfg.vmc_out.len(), 1);
        assert!(
            matches!(&cfg.sources[0], SourceSpec::ReplayFile(crate::config::ReplayFileSpec { path, .. }) if path.ends_with("recordings/demo.rcr"))
        );
        assert_eq!(cfg.performers.len(), 1);
        assert_eq!(cfg.performers[0].sources, vec!["demo".to_string()]);
        assert!(
            matches!(&cfg.performers[0].target, TargetSpec::File(p) if p == Path::new("builtin:mannequin"))
        );
        assert_eq!(cfg.on_lost, OnLost::Ease);
        assert!(cfg.mapping_cache_dir.is_some() || std::env::var_os("HOME").is_none());
    }

    #[test]
    fn idle_graph_implies_idle_and_idle_needs_a_graph() {
        let parse = |t: &str| ServerConfig::from_file(toml::from_str(t).unwrap());
        let cfg = parse(
            "[[performers]]\ntarget = \"builtin:mannequin\"\nidle_graph = \"/x/idle.rmg\"\nresume_secs = 0.5",
        )
        .unwrap();
        let p = &cfg.performers[0];
        assert_eq!(p.on_lost, Some(OnLost::Idle));
        assert_eq!(p.idle_graph, Some(PathBuf::from("/x/idle.rmg")));
        assert_eq!(p.resume_secs, Some(0.5));
        let no_graph = parse("on_lost = \"idle\"\n[[performers]]\ntarget = \"builtin:mannequin\"");
        assert!(no_graph.unwrap_err().to_string().contains("idle_graph"));
        let conflict = parse(
            "[[performers]]\ntarget = \"builtin:mannequin\"\nidle_graph = \"/x/i.rmg\"\non_lost = \"hold\"",
        );
        assert!(conflict.unwrap_err().to_string().contains("idle"));
        let bad_time = parse(
            "[[performers]]\ntarget = \"builtin:mannequin\"\nidle_graph = \"/x/i.rmg\"\nresume_secs = -1",
        );
        assert!(bad_time.unwrap_err().to_string().contains("resume_secs"));
        let clips = parse(
            "[[performers]]\ntarget = \"builtin:mannequin\"\nidle_graph = \"/x/i.rmg\"\nidle_clips = [\"idle\", \"2\"]",
        )
        .unwrap();
        assert_eq!(clips.performers[0].idle_clips, ["idle", "2"]);
        let orphan =
            parse("[[performers]]\ntarget = \"builtin:mannequin\"\nidle_clips = [\"idle\"]");
        assert!(orphan.unwrap_err().to_string().contains("idle_clips"));
    }

    #[test]
    fn parses_live_sources_performers_and_vmc_subjects() {
        let text = r#"
            on_lost = "hold"
            record = "/tmp/x.rcr"
            mapping_cache = false
            vmc_bone_names = "skeleton"
            vmc_out = ["127.0.0.1:1", { address = "127.0.0.1:2", subject = "hero" }]
            [[sources]]
            kind = "vmc"
            port = 39540
            name = "face"
            [[sources]]
            kind = "serial"
            config = "/x/suit.toml"
            [[sources]]
            kind = "webcam"
            index = 1
            [[performers]]
            source = ["face", "suit"]
            target = "/x/hero.glb"
            in_place = true
            on_lost = "ease"
            foot_lock = false
        "#;
        let cfg = ServerConfig::from_file(toml::from_str(text).unwrap()).unwrap();
        assert_eq!(cfg.on_lost, OnLost::Hold);
        assert_eq!(cfg.vmc_bone_names, VmcBoneNames::Skeleton);
        assert!(cfg.mapping_cache_dir.is_none());
        assert_eq!(cfg.record, Some(PathBuf::from("/tmp/x.rcr")));
        assert_eq!(
            cfg.vmc_out,
            vec![
                VmcOut::to("127.0.0.1:1"),
                "127.0.0.1:2@hero".parse().unwrap()
            ]
        );
        assert!(matches!(
            cfg.sources[0],
            SourceSpec::Vmc(crate::config::VmcSpec { port: 39540, .. })
        ));
        assert!(
            matches!(&cfg.sources[1], SourceSpec::Serial(crate::config::SerialSpec { config, .. }) if config == Path::new("/x/suit.toml"))
        );
        assert!(matches!(
            cfg.sources[2],
            SourceSpec::Webcam(crate::config::WebcamSpec {
                index: 1,
                person: None,
                name: None,
                ..
            })
        ));
        let p = &cfg.performers[0];
        assert_eq!(p.sources, vec!["face".to_string(), "suit".to_string()]);
        assert!(p.in_place);
        assert_eq!(p.on_lost, Some(OnLost::Ease));
        assert_eq!(p.foot_lock, Some(false));
        assert!(toml::from_str::<FileConfig>("on_lost = \"drop\"").is_err());
    }

    #[test]
    fn parses_access_limits_and_vmc_bind() {
        let text = r#"
            allowed_origins = ["http://localhost:3000"]
            allowed_hosts = ["studio.lan"]
            token_file = "/x/token"
            max_connections = 100
            stalled_client_timeout_secs = 2.5
            mapping_cache_max_entries = 7
            [[sources]]
            kind = "vmc"
            port = 39540
            [[sources]]
            kind = "vmc"
            port = 39541
            bind = "0.0.0.0"
            allowed_senders = ["192.168.1.20"]
        "#;
        let cfg = ServerConfig::from_file(toml::from_str(text).unwrap()).unwrap();
        assert_eq!(cfg.access.allowed_origins, vec!["http://localhost:3000"]);
        assert_eq!(cfg.access.allowed_hosts, vec!["studio.lan"]);
        assert_eq!(
            cfg.access.token,
            TokenSetting::File(PathBuf::from("/x/token"))
        );
        assert_eq!(cfg.limits.max_connections, Some(100));
        assert_eq!(cfg.limits.stalled_client_timeout_secs, 2.5);
        assert_eq!(cfg.limits.mapping_cache_max_entries, 7);
        // VMC input stays on loopback unless the file says otherwise.
        assert!(matches!(
            &cfg.sources[0],
            SourceSpec::Vmc(crate::config::VmcSpec { bind, allowed_senders, .. }) if bind.is_loopback() && allowed_senders.is_empty()
        ));
        assert!(matches!(
            &cfg.sources[1],
            SourceSpec::Vmc(crate::config::VmcSpec { bind, allowed_senders, .. })
                if bind.is_unspecified() && allowed_senders == &["192.168.1.20".parse::<IpAddr>().unwrap()]
        ));
        // The library default keeps the token in memory; a file config uses a file.
        assert_eq!(
            ServerConfig::default().access.token,
            TokenSetting::Ephemeral
        );
        for bad in [
            "stalled_client_timeout_secs = 0",
            "max_connections = 0",
            "mapping_cache_max_entries = 0",
        ] {
            let file: FileConfig = toml::from_str(bad).unwrap();
            assert!(ServerConfig::from_file(file).is_err(), "{bad}");
        }
    }

    #[test]
    fn rejects_bad_values() {
        assert!(
            toml::from_str::<FileConfig>("rate = 3").is_err(),
            "unknown key"
        );
        let file: FileConfig = toml::from_str("rate_hz = 500").unwrap();
        assert!(matches!(
            ServerConfig::from_file(file),
            Err(ConfigError::Invalid {
                field: "rate_hz",
                ..
            })
        ));
        let file: FileConfig = toml::from_str(r#"listen = "nope""#).unwrap();
        assert!(ServerConfig::from_file(file).is_err());
        let file: FileConfig =
            toml::from_str("[[sources]]\nkind = \"replay\"\npath = \"a\"\nspeed = 0").unwrap();
        assert!(ServerConfig::from_file(file).is_err());
    }

    #[test]
    fn unknown_keys_are_errors_naming_the_key_and_the_file() {
        let dir = std::env::temp_dir().join(format!("rigcast-keys-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("studio.toml");
        for (text, key) in [
            ("rate = 3\n", "rate"),
            (
                "[[sources]]\nkind = \"replay\"\npath = \"a.bvh\"\nsped = 2\n",
                "sped",
            ),
            ("[[sources]]\nkind = \"vmc\"\nprot = 39540\n", "prot"),
            ("[[sources]]\nkind = \"teleport\"\n", "teleport"),
            (
                "vmc_out = [{ address = \"127.0.0.1:1\", subjct = \"x\" }]\n",
                "subjct",
            ),
            (
                "[[performers]]\ntarget = \"a.glb\"\nfootlock = true\n",
                "footlock",
            ),
        ] {
            std::fs::write(&path, text).unwrap();
            let err = FileConfig::load(&path).unwrap_err().to_string();
            assert!(err.contains("studio.toml"), "{text}: {err}");
            assert!(err.contains(&format!("`{key}`")), "{text}: {err}");
        }
    }

    #[test]
    fn cli_grammar_round_trips_through_the_spec() {
        for arg in [
            "demo",
            "replay:walk.bvh",
            "replay:/x/y z.rcr",
            "vmc:39540",
            "vmc:0",
            "vmc:0.0.0.0:39541",
            "vmc:[::1]:39542",
            "serial:suit.toml",
            "video:clip.mp4",
            "video:clip.mp4#1",
            "video:/x/two people.mp4#0",
            "webcam:2",
            "webcam:0#1",
            "webcam:1#1?width=1280&height=720&fps=60&format=mjpeg",
            "webcam:0?fps=30&model=full",
            "webcam:0?model=lite",
        ] {
            let spec: SourceSpec = arg.parse().unwrap();
            assert_eq!(spec.to_cli().as_deref(), Some(arg), "{spec:?}");
        }
        let spec: SourceSpec = "vmc:0.0.0.0:39541".parse().unwrap();
        assert_eq!(spec.kind(), SourceKind::Vmc);
        // The file spelling and the command-line spelling give the same spec.
        let file: FileConfig =
            toml::from_str("[[sources]]\nkind = \"vmc\"\nport = 39540\n").unwrap();
        let cli: SourceSpec = "vmc:39540".parse().unwrap();
        assert_eq!(format!("{:?}", file.sources[0]), format!("{cli:?}"));
        let named = SourceSpec::Serial(crate::config::SerialSpec {
            config: "suit.toml".into(),
            name: Some("suit".into()),
        });
        assert_eq!(named.to_cli(), None, "a name has no command-line spelling");
        for (bad, says) in [
            ("teleport:x", "unknown source"),
            ("replay:", "unknown source"),
            ("vmc:nope", "vmc:PORT"),
            ("webcam:front", "webcam:INDEX"),
            ("webcam:0#one", "webcam:INDEX#PERSON"),
            ("webcam:0?model=huge", "model=lite|full"),
            ("video:clip.mp4#one", "video:FILE#PERSON"),
            ("video:clip.mp4#-1", "video:FILE#PERSON"),
            ("video:#1", "unknown source"),
        ] {
            let err = bad.parse::<SourceSpec>().unwrap_err().to_string();
            assert!(err.contains(says), "{bad}: {err}");
        }
        // `person` in a [[sources]] entry is the same spec as `#PERSON`.
        let file: FileConfig =
            toml::from_str("[[sources]]\nkind = \"video\"\npath = \"a.mp4\"\nperson = 1\n")
                .unwrap();
        let cli: SourceSpec = "video:a.mp4#1".parse().unwrap();
        assert_eq!(format!("{:?}", file.sources[0]), format!("{cli:?}"));
        // The model is a key of both vision kinds, checked before anything opens.
        for (text, ok) in [
            ("kind = \"webcam\"\nmodel = \"full\"", true),
            (
                "kind = \"video\"\npath = \"a.mp4\"\nmodel = \"heavy\"",
                true,
            ),
            ("kind = \"webcam\"\nmodel = \"huge\"", false),
            (
                "kind = \"video\"\npath = \"a.mp4\"\nmodel = \"Lite\"",
                false,
            ),
        ] {
            let file: FileConfig = toml::from_str(&format!("[[sources]]\n{text}\n")).unwrap();
            let checked = file.sources[0].validate();
            assert_eq!(checked.is_ok(), ok, "{text}: {checked:?}");
            if let Err(e) = checked {
                assert!(e.to_string().contains("model"), "{e}");
            }
        }
        let out: VmcOut = "127.0.0.1:2@hero".parse().unwrap();
        assert_eq!(out.subject.as_deref(), Some("hero"));
        assert_eq!(out.to_string(), "127.0.0.1:2@hero");
    }
}
