//! A serial IMU suit (`kind = "serial"`, `--source serial:CONFIG.toml`).

use std::path::PathBuf;

use anyhow::Context;
use rigcast_protocol::SourceKind;
use rigcast_sources::live::LiveSource;
use rigcast_sources::serial::{SerialImuConfig, SerialImuSource};
use serde::Deserialize;

use super::{file_arg, stem, CliError, KindSpec, Loaded, Opened};

/// A suit described by a TOML file (see `SerialImuConfig`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSpec {
    /// The suit's TOML config.
    pub config: PathBuf,
    /// Subject name (default: the config file stem).
    pub name: Option<String>,
}

impl KindSpec for SerialSpec {
    const KIND: SourceKind = SourceKind::Serial;
    const CLI: Option<&'static str> = Some("serial");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        Ok(SerialSpec {
            config: file_arg(arg)?,
            name: None,
        })
    }

    fn to_cli(&self) -> Option<String> {
        self.name
            .is_none()
            .then(|| format!("serial:{}", self.config.display()))
    }

    fn file_mut(&mut self) -> Option<&mut PathBuf> {
        Some(&mut self.config)
    }

    fn open(self) -> anyhow::Result<Opened> {
        let config = &self.config;
        let text = std::fs::read_to_string(config)
            .with_context(|| format!("cannot read serial config {}", config.display()))?;
        let cfg = SerialImuConfig::from_toml(&text)
            .with_context(|| format!("serial config {}", config.display()))?;
        let humanoid = rigcast_sources::live::humanoid::default_humanoid()
            .context("building the default humanoid")?;
        let source = SerialImuSource::open(cfg, humanoid.clone())
            .with_context(|| format!("cannot open the serial suit of {}", config.display()))?;
        let sk = source.skeleton().unwrap_or(humanoid);
        let name = self.name.unwrap_or_else(|| stem(config));
        let calibration = Some(source.calibration_handle());
        let loaded = Loaded::Live {
            source: Box::new(source),
            kind: SourceKind::Serial,
            listen: None,
            calibration,
        };
        Ok((name, loaded, sk))
    }
}
