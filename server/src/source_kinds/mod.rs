//! Source kinds: everything about one kind of input in one module — its `[[sources]]` keys,
//! its `--source KIND:ARG` grammar, its checks and how it opens.
//!
//! ```text
//!  rigcast.toml [[sources]] ─serde (kind = …)─┐
//!  --source KIND:ARG ───────FromStr──────────┴─▶ SourceSpec::Kind(KindSpec) ─open()─▶ Opened
//!                                                 (one arm per kind)          (boot/load)
//! ```
//!
//! Adding a kind: write its module (a spec struct implementing [`KindSpec`]) and add one line
//! to the `source_kinds!` list below (plus its wire name in `rigcast_protocol::SourceKind`
//! when it is a new kind of input rather than a new way to start an existing one). The list
//! generates the [`SourceSpec`] enum and every dispatch over it, so nothing else changes.

mod replay;
mod serial;
mod video;
mod vision_inputs;
mod vmc;
mod webcam;

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;

use rigcast_protocol::SourceKind;
use rigcast_retarget::{Pose, Skeleton};
use rigcast_sources::live::LiveSource;
use rigcast_sources::serial::CalibrationHandle;
use rigcast_sources::Replay;
use serde::Deserialize;

use crate::config_error::ConfigError;

pub use replay::{demo_clip, DemoSpec, ReplayClipSpec, ReplayFileSpec, ReplaySettings};
pub use serial::SerialSpec;
pub use video::VideoSpec;
pub(crate) use vision_inputs::VisionInputs;
pub use vmc::{VmcSpec, DEFAULT_VMC_BIND};
pub use webcam::{WebcamSpec, NO_WEBCAM_HINT};

/// One kind of source: its spec (the `[[sources]]` entry's keys, `kind` aside) and what it
/// does. Implemented by each kind's module; dispatched by [`SourceSpec`].
pub(crate) trait KindSpec: Sized {
    /// What `source_status` and `/v1/status` call it.
    const KIND: SourceKind;
    /// The `--source` prefix (`vmc` in `vmc:PORT`); `None` when the command line cannot say
    /// it (a clip in memory).
    const CLI: Option<&'static str>;
    /// Parses the `--source` argument after `PREFIX:` (empty when there is no colon).
    fn parse_cli(arg: &str) -> Result<Self, CliError>;
    /// The `--source` argument that parses back into this spec, or `None` when the command
    /// line cannot say it (names, non-default settings).
    fn to_cli(&self) -> Option<String>;
    /// The file it reads, if any (resolved against a config file's folder).
    fn file_mut(&mut self) -> Option<&mut PathBuf> {
        None
    }
    /// Checks values serde cannot (ranges).
    fn validate(&self) -> Result<(), ConfigError> {
        Ok(())
    }
    /// Opens it. Blocks (files, devices, model loading): call from `spawn_blocking`.
    fn open(self) -> anyhow::Result<Opened>;
}

/// Why a `--source` argument of a known kind does not parse.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CliError {
    /// Not this kind's grammar at all (e.g. an empty file name).
    Unknown,
    /// The kind's grammar, said in the error.
    Expected(&'static str),
}

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
        listen: Option<std::net::SocketAddr>,
        /// Set for calibratable sources (serial IMU suits).
        calibration: Option<CalibrationHandle>,
    },
}

impl Loaded {
    /// A live source that neither listens on a port nor calibrates.
    pub(crate) fn live(source: Box<dyn LiveSource>, kind: SourceKind) -> Loaded {
        Loaded::Live {
            source,
            kind,
            listen: None,
            calibration: None,
        }
    }
}

/// An opened source: its subject name, what runs it and its (initial) skeleton.
pub(crate) type Opened = (String, Loaded, Arc<Skeleton>);

/// Generates [`SourceSpec`] and its dispatch from the list of kinds.
macro_rules! source_kinds {
    ($( $(#[$meta:meta])* $variant:ident($spec:ty), )*) => {
        /// Where a subject's poses come from. One schema for both spellings: a `[[sources]]`
        /// entry deserialises straight into it (`kind` picks the variant, unknown keys are
        /// errors), and `--source KIND:ARG` parses into it ([`FromStr`];
        /// [`SourceSpec::to_cli`] writes it back).
        #[derive(Debug, Clone, Deserialize)]
        #[serde(tag = "kind", rename_all = "snake_case")]
        pub enum SourceSpec {
            $( $(#[$meta])* $variant($spec), )*
        }

        impl SourceSpec {
            /// What kind of source this is.
            pub fn kind(&self) -> SourceKind {
                match self { $( SourceSpec::$variant(_) => <$spec as KindSpec>::KIND, )* }
            }

            /// The file this source reads, if any.
            pub fn file_mut(&mut self) -> Option<&mut PathBuf> {
                match self { $( SourceSpec::$variant(s) => s.file_mut(), )* }
            }

            /// The `--source` argument that parses back into this spec, or `None` when the
            /// command line cannot say it (an in-memory clip, names, non-default settings).
            pub fn to_cli(&self) -> Option<String> {
                match self { $( SourceSpec::$variant(s) => s.to_cli(), )* }
            }

            /// Checks values serde cannot (ranges).
            pub fn validate(&self) -> Result<(), ConfigError> {
                match self { $( SourceSpec::$variant(s) => s.validate(), )* }
            }

            /// Opens the source (blocking; see [`KindSpec::open`]).
            pub(crate) fn open(self) -> anyhow::Result<Opened> {
                match self { $( SourceSpec::$variant(s) => s.open(), )* }
            }

            /// The spec of `--source PREFIX:ARG`, or `None` for an unknown prefix.
            fn parse_cli(prefix: &str, arg: &str) -> Option<Result<SourceSpec, CliError>> {
                $( if <$spec as KindSpec>::CLI == Some(prefix) {
                    return Some(<$spec as KindSpec>::parse_cli(arg).map(SourceSpec::$variant));
                } )*
                None
            }
        }
    };
}

source_kinds! {
    /// Replay a file (`kind = "replay"`: `path`, `speed`, `loop`, `start_offset_secs`,
    /// `name`; `--source replay:FILE`).
    #[serde(rename = "replay")]
    ReplayFile(ReplayFileSpec),
    /// Replay a clip already in memory (tests, generated content).
    #[serde(skip)]
    ReplayClip(ReplayClipSpec),
    /// The bundled demo recording, looping (`--source demo`).
    #[serde(skip)]
    EmbeddedDemo(DemoSpec),
    /// VMC/OSC input (`--source vmc:PORT` on loopback, `vmc:ADDR:PORT` elsewhere).
    Vmc(VmcSpec),
    /// Serial IMU suit described by a TOML file (`--source serial:CONFIG.toml`).
    Serial(SerialSpec),
    /// Pose estimation on a video file (`--source video:FILE`).
    Video(VideoSpec),
    /// Pose estimation on a webcam (`--source webcam:INDEX`).
    Webcam(WebcamSpec),
}

impl SourceSpec {
    /// Opens the source like [`SourceSpec::open`], except that video and webcam subjects of
    /// one file or camera share its pipeline through `vision` (one per configuration).
    pub(crate) fn open_with(self, vision: &VisionInputs) -> anyhow::Result<Opened> {
        match self {
            SourceSpec::Video(s) => s.open_shared(vision),
            SourceSpec::Webcam(s) => s.open_shared(vision),
            other => other.open(),
        }
    }

    /// The bundled demo.
    pub fn demo() -> SourceSpec {
        SourceSpec::EmbeddedDemo(DemoSpec)
    }
}

/// `--source` arguments: `KIND:ARG` (`replay:PATH`, `vmc:PORT`, `vmc:ADDR:PORT`,
/// `serial:CONFIG.toml`, `video:FILE`, `webcam:INDEX`) or a bare `demo`.
impl FromStr for SourceSpec {
    type Err = ConfigError;

    fn from_str(s: &str) -> Result<SourceSpec, ConfigError> {
        let (prefix, arg) = s.split_once(':').unwrap_or((s, ""));
        let unknown = || ConfigError::UnknownSource { text: s.into() };
        match SourceSpec::parse_cli(prefix, arg) {
            None | Some(Err(CliError::Unknown)) => Err(unknown()),
            Some(Err(CliError::Expected(expected))) => Err(ConfigError::BadSourceArg {
                text: s.into(),
                expected,
            }),
            Some(Ok(spec)) => Ok(spec),
        }
    }
}

/// A file argument: any non-empty text.
fn file_arg(arg: &str) -> Result<PathBuf, CliError> {
    (!arg.is_empty())
        .then(|| PathBuf::from(arg))
        .ok_or(CliError::Unknown)
}

/// A file's stem, the default subject name of file sources.
fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}
