//! `rigcast serve`: load sources, start the server, print its URLs, run until Ctrl-C.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::config::{parse_listen, FileConfig, ReplaySettings, ServerConfig, SourceSpec};

/// Options of `rigcast serve`. Flags override `--config`.
#[derive(Debug, Args, Default)]
pub struct ServeArgs {
    /// Config file (TOML); see `rigcast.toml` docs.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A source, e.g. `replay:walk.bvh` (repeatable). Replaces the config's sources.
    #[arg(long = "source", value_name = "KIND:ARG")]
    pub sources: Vec<String>,
    /// Listen address (default 127.0.0.1:8717; port 0 picks a free one).
    #[arg(long)]
    pub listen: Option<String>,
    /// VMC receiver HOST:PORT (repeatable). Replaces the config's list.
    #[arg(long = "vmc-out", value_name = "HOST:PORT")]
    pub vmc_out: Vec<String>,
    /// Output rate in Hz (1..=240, default 60).
    #[arg(long)]
    pub rate: Option<f64>,
}

/// Merges the config file and flags.
pub fn resolve(args: &ServeArgs) -> anyhow::Result<ServerConfig> {
    let mut cfg = match &args.config {
        Some(path) => ServerConfig::from_file(FileConfig::load(path)?)?,
        None => ServerConfig::default(),
    };
    if let Some(listen) = &args.listen {
        cfg.listen = parse_listen(listen)?;
    }
    if let Some(rate) = args.rate {
        cfg.rate_hz = rate;
    }
    if !args.vmc_out.is_empty() {
        cfg.vmc_out = args.vmc_out.clone();
    }
    if !args.sources.is_empty() {
        cfg.sources = args
            .sources
            .iter()
            .map(|s| parse_source(s))
            .collect::<anyhow::Result<_>>()?;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// Parses `replay:PATH` (and `demo`).
pub fn parse_source(s: &str) -> anyhow::Result<SourceSpec> {
    if s == "demo" {
        return Ok(SourceSpec::EmbeddedDemo);
    }
    match s.split_once(':') {
        Some(("replay", path)) if !path.is_empty() => Ok(SourceSpec::ReplayFile {
            path: PathBuf::from(path),
            name: None,
            settings: ReplaySettings::default(),
        }),
        _ => anyhow::bail!("unknown source {s:?}; expected replay:FILE or demo"),
    }
}

/// Runs the server until Ctrl-C.
pub async fn run(args: ServeArgs) -> anyhow::Result<()> {
    let cfg = resolve(&args)?;
    let handle = crate::start(cfg.clone()).await?;
    let addr = handle.local_addr();
    println!("rigcast {} listening", env!("CARGO_PKG_VERSION"));
    println!("  stream: ws://{addr}/v1/stream");
    println!("  status: http://{addr}/v1/status");
    println!("  viewer: http://{addr}/");
    for s in handle.state().subjects.iter() {
        println!(
            "  subject {}: {} ({} bones)",
            s.info.id, s.info.name, s.info.num_bones
        );
    }
    for v in &cfg.vmc_out {
        println!("  vmc out: {v}");
    }
    tokio::signal::ctrl_c()
        .await
        .context("waiting for Ctrl-C")?;
    println!("rigcast: shutting down");
    handle.shutdown().await;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_override_defaults() {
        let args = ServeArgs {
            listen: Some("127.0.0.1:0".into()),
            rate: Some(30.0),
            sources: vec!["replay:a.bvh".into()],
            ..ServeArgs::default()
        };
        let cfg = resolve(&args).unwrap();
        assert_eq!(cfg.listen.port(), 0);
        assert_eq!(cfg.rate_hz, 30.0);
        assert!(
            matches!(&cfg.sources[0], SourceSpec::ReplayFile { path, .. } if path == &PathBuf::from("a.bvh"))
        );
        assert!(parse_source("webcam").is_err());
        let bad_rate = ServeArgs {
            rate: Some(0.5),
            ..ServeArgs::default()
        };
        assert!(resolve(&bad_rate).is_err());
    }
}
