//! Replayed sources: a file (`kind = "replay"`), a clip in memory, the bundled demo.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use rigcast_protocol::SourceKind;
use rigcast_retarget::Clip;
use rigcast_sources::{load_clip_and_humanoid, LoadOptions, LoadedClip, Replay, ReplayOptions};
use serde::Deserialize;

use super::{file_arg, CliError, KindSpec, Loaded, Opened, SourceSpec};
use crate::config_error::ConfigError;

/// Playback settings of a replayed clip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplaySettings {
    /// Speed factor (> 0).
    pub speed: f64,
    /// Loop at the end.
    pub looping: bool,
    /// Seconds into the clip to start at.
    pub start_offset_secs: f64,
}

impl Default for ReplaySettings {
    fn default() -> Self {
        ReplaySettings {
            speed: 1.0,
            looping: true,
            start_offset_secs: 0.0,
        }
    }
}

// The replay constructors live with the replay specs they make.
impl SourceSpec {
    /// A file replayed with default settings, named after the file.
    pub fn replay_file(path: impl Into<PathBuf>) -> SourceSpec {
        SourceSpec::ReplayFile(ReplayFileSpec {
            path: path.into(),
            name: None,
            settings: ReplaySettings::default(),
        })
    }

    /// A clip in memory replayed with default settings, named after the clip.
    pub fn replay_clip(clip: Clip) -> SourceSpec {
        SourceSpec::ReplayClip(ReplayClipSpec {
            clip,
            name: None,
            settings: ReplaySettings::default(),
        })
    }
}

impl ReplaySettings {
    fn validate(&self) -> Result<(), ConfigError> {
        if !(self.speed.is_finite() && self.speed > 0.0) {
            return Err(ConfigError::Invalid {
                field: "speed",
                message: format!("{} must be a positive number", self.speed),
            });
        }
        if !(self.start_offset_secs.is_finite() && self.start_offset_secs >= 0.0) {
            return Err(ConfigError::Invalid {
                field: "start_offset_secs",
                message: format!("{} must be ≥ 0", self.start_offset_secs),
            });
        }
        Ok(())
    }
}

/// A file played back (BVH, glTF/GLB/VRM, .rcr).
#[derive(Debug, Clone, Deserialize)]
#[serde(from = "ReplayKeys")]
pub struct ReplayFileSpec {
    /// The file (relative paths in a config file are relative to it).
    pub path: PathBuf,
    /// Subject name (default: file stem).
    pub name: Option<String>,
    /// Playback.
    pub settings: ReplaySettings,
}

/// The keys of a `kind = "replay"` entry, flat in the file, grouped in [`ReplayFileSpec`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ReplayKeys {
    path: PathBuf,
    #[serde(default = "one")]
    speed: f64,
    #[serde(default = "yes", rename = "loop")]
    looping: bool,
    #[serde(default)]
    start_offset_secs: f64,
    name: Option<String>,
}

fn one() -> f64 {
    1.0
}

fn yes() -> bool {
    true
}

impl From<ReplayKeys> for ReplayFileSpec {
    fn from(k: ReplayKeys) -> ReplayFileSpec {
        let settings = ReplaySettings {
            speed: k.speed,
            looping: k.looping,
            start_offset_secs: k.start_offset_secs,
        };
        ReplayFileSpec {
            path: k.path,
            name: k.name,
            settings,
        }
    }
}

impl KindSpec for ReplayFileSpec {
    const KIND: SourceKind = SourceKind::Replay;
    const CLI: Option<&'static str> = Some("replay");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        Ok(ReplayFileSpec {
            path: file_arg(arg)?,
            name: None,
            settings: ReplaySettings::default(),
        })
    }

    fn to_cli(&self) -> Option<String> {
        (self.name.is_none() && self.settings == ReplaySettings::default())
            .then(|| format!("replay:{}", self.path.display()))
    }

    fn file_mut(&mut self) -> Option<&mut PathBuf> {
        Some(&mut self.path)
    }

    fn validate(&self) -> Result<(), ConfigError> {
        self.settings.validate()
    }

    /// Reads the file; a VRM's humanoid map comes along.
    fn open(self) -> anyhow::Result<Opened> {
        let LoadedClip {
            clip,
            humanoid: truth,
        } = load_clip_and_humanoid(&self.path, &LoadOptions::default())
            .with_context(|| format!("cannot load source {}", self.path.display()))?;
        let name = self.name.unwrap_or_else(|| {
            self.path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| clip.name.clone())
        });
        replay_of(name, clip, self.settings, truth)
    }
}

/// A clip already in memory (tests, generated content).
#[derive(Debug, Clone)]
pub struct ReplayClipSpec {
    /// The clip.
    pub clip: Clip,
    /// Subject name (default: the clip name).
    pub name: Option<String>,
    /// Playback.
    pub settings: ReplaySettings,
}

impl KindSpec for ReplayClipSpec {
    const KIND: SourceKind = SourceKind::Replay;
    const CLI: Option<&'static str> = None;

    fn parse_cli(_: &str) -> Result<Self, CliError> {
        Err(CliError::Unknown)
    }

    fn to_cli(&self) -> Option<String> {
        None
    }

    fn validate(&self) -> Result<(), ConfigError> {
        self.settings.validate()
    }

    fn open(self) -> anyhow::Result<Opened> {
        let name = self.name.unwrap_or_else(|| self.clip.name.clone());
        replay_of(name, self.clip, self.settings, None)
    }
}

/// The bundled demo recording, looping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DemoSpec;

impl KindSpec for DemoSpec {
    const KIND: SourceKind = SourceKind::Replay;
    const CLI: Option<&'static str> = Some("demo");

    /// A bare `demo`: no argument.
    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        arg.is_empty().then_some(DemoSpec).ok_or(CliError::Unknown)
    }

    fn to_cli(&self) -> Option<String> {
        Some("demo".into())
    }

    fn open(self) -> anyhow::Result<Opened> {
        replay_of("demo".into(), demo_clip()?, ReplaySettings::default(), None)
    }
}

/// A clip played back as subject `name`.
fn replay_of(
    name: String,
    clip: Clip,
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

fn replay(clip: Clip, settings: ReplaySettings) -> anyhow::Result<Replay> {
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
pub fn demo_clip() -> anyhow::Result<Clip> {
    match rigcast_sources::embedded_demo() {
        Ok(clip) if clip.num_frames() > 0 => Ok(clip),
        Ok(_) => Ok(crate::demo::procedural_clip(120, 30.0)?),
        Err(e) => {
            tracing::warn!("bundled demo unavailable ({e}); using the procedural demo");
            Ok(crate::demo::procedural_clip(120, 30.0)?)
        }
    }
}
