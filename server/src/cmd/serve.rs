//! `rigcast serve`: load sources, start the server, print its URLs, run until Ctrl-C.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::access::BindScope;
use crate::config::{
    default_mapping_cache_dir, parse_listen, AccessConfig, FileConfig, PerformerSpec, ServerConfig,
    SourceSpec,
};
use crate::token::TokenSetting;
use rigcast_engine::settings::OnLost;

/// Options of `rigcast serve`. Flags override `--config`.
#[derive(Debug, Args, Default)]
pub struct ServeArgs {
    /// Config file (TOML); keys in the README's configuration reference and server/rigcast.example.toml.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A source, e.g. `replay:walk.bvh` (repeatable). Replaces the config's sources.
    #[arg(long = "source", value_name = "KIND:ARG")]
    pub sources: Vec<String>,
    /// Listen address (default 127.0.0.1:8717; port 0 picks a free one).
    #[arg(long)]
    pub listen: Option<String>,
    /// VMC receiver HOST:PORT, or HOST:PORT@SUBJECT for another subject than the first
    /// target (repeatable). Replaces the config's list.
    #[arg(long = "vmc-out", value_name = "HOST:PORT")]
    pub vmc_out: Vec<String>,
    /// Output rate in Hz (1..=240, default 60).
    #[arg(long)]
    pub rate: Option<f64>,
    /// A character to retarget onto (BVH, glTF/GLB, VRM, .rcr; its animation is ignored;
    /// `builtin:mannequin`), driven by the first source (repeatable). Replaces the config's
    /// performers.
    #[arg(long = "target", value_name = "FILE")]
    pub targets: Vec<PathBuf>,
    /// Record every subject and the raw input of live sources into FILE.rcr.
    #[arg(long, value_name = "FILE.rcr")]
    pub record: Option<PathBuf>,
    /// While a source is lost its targets ease to their own rest pose (`rest`, or `ease`, the
    /// default) or hold the last pose (`hold`).
    #[arg(long = "on-lost", value_name = "rest|hold")]
    pub on_lost: Option<String>,
    /// Don't read or write the on-disk mapping cache.
    #[arg(long)]
    pub no_mapping_cache: bool,
    /// Allow web pages of this origin (e.g. `http://localhost:3000`) besides the served
    /// viewer (repeatable; adds to the config's `allowed_origins`).
    #[arg(long = "allow-origin", value_name = "ORIGIN")]
    pub allowed_origins: Vec<String>,
    /// The control token's file (default `$XDG_CONFIG_HOME/rigcast/token`).
    #[arg(long, value_name = "PATH")]
    pub token_file: Option<PathBuf>,
    /// Most simultaneous connections (default: the open-file limit minus 64).
    #[arg(long, value_name = "N")]
    pub max_connections: Option<usize>,
    /// Cluster mode: NATS servers to share subjects through (`nats://HOST:PORT[,…]`).
    #[arg(long, value_name = "URL[,URL…]", requires = "site")]
    pub nats: Option<String>,
    /// Cluster mode: this node's name in the deployment.
    #[arg(long, value_name = "NAME", requires = "nats")]
    pub site: Option<String>,
}

/// Merges the config file and flags.
pub fn resolve(args: &ServeArgs) -> anyhow::Result<ServerConfig> {
    let mut cfg = match &args.config {
        Some(path) => ServerConfig::from_file(FileConfig::load(path)?)?,
        None => flagless_config(),
    };
    apply_access_flags(args, &mut cfg);
    apply_cluster_flags(args, &mut cfg)?;
    apply_run_flags(args, &mut cfg)?;
    cfg.validate()?;
    Ok(cfg)
}

/// The configuration without a file: the default mapping cache, the default token file (or a
/// token for this run only where there is no home to keep one).
fn flagless_config() -> ServerConfig {
    ServerConfig {
        mapping_cache_dir: default_mapping_cache_dir(),
        access: AccessConfig {
            token: crate::token::default_token_path()
                .map(TokenSetting::File)
                .unwrap_or(TokenSetting::Ephemeral),
            ..AccessConfig::default()
        },
        ..ServerConfig::default()
    }
}

/// `--token-file`, `--allowed-origin`, `--max-connections`, `--no-mapping-cache`.
fn apply_access_flags(args: &ServeArgs, cfg: &mut ServerConfig) {
    if let Some(t) = &args.token_file {
        cfg.access.token = TokenSetting::File(t.clone());
    }
    cfg.access
        .allowed_origins
        .extend(args.allowed_origins.iter().cloned());
    if args.max_connections.is_some() {
        cfg.limits.max_connections = args.max_connections;
    }
    if args.no_mapping_cache {
        cfg.mapping_cache_dir = None;
    }
}

/// `--nats` and `--site`: they override the file's servers and site; its credentials and
/// namespace stay.
fn apply_cluster_flags(args: &ServeArgs, cfg: &mut ServerConfig) -> anyhow::Result<()> {
    if let (Some(servers), Some(site)) = (&args.nats, &args.site) {
        let mut c = cfg
            .cluster
            .take()
            .unwrap_or_else(|| crate::cluster::ClusterConfig::new(servers, site));
        c.servers = crate::cluster::ClusterConfig::new(servers, site).servers;
        c.site = site.clone();
        c.validate()?;
        cfg.cluster = Some(c);
    }
    Ok(())
}

/// What runs: `--target`, `--record`, `--on-lost`, `--listen`, `--rate`, `--vmc-out`,
/// `--source`.
fn apply_run_flags(args: &ServeArgs, cfg: &mut ServerConfig) -> anyhow::Result<()> {
    if !args.targets.is_empty() {
        cfg.performers = args
            .targets
            .iter()
            .map(|t| PerformerSpec::target_file(t.clone()))
            .collect();
    }
    if let Some(r) = &args.record {
        cfg.record = Some(r.clone());
    }
    if let Some(o) = &args.on_lost {
        cfg.on_lost = <OnLost as clap::ValueEnum>::from_str(o, false)
            .map_err(|_| anyhow::anyhow!("--on-lost {o:?}: expected rest (ease), hold or idle"))?;
    }
    if let Some(listen) = &args.listen {
        cfg.listen = parse_listen(listen)?;
    }
    if let Some(rate) = args.rate {
        cfg.rate_hz = rate;
    }
    if !args.vmc_out.is_empty() {
        cfg.vmc_out = args
            .vmc_out
            .iter()
            .map(|v| v.parse())
            .collect::<Result<_, _>>()?;
    }
    if !args.sources.is_empty() {
        cfg.sources = args
            .sources
            .iter()
            .map(|s| s.parse())
            .collect::<Result<_, _>>()?;
    }
    Ok(())
}

/// Parses a `--source` argument (see [`SourceSpec`]'s `FromStr`).
pub fn parse_source(s: &str) -> anyhow::Result<SourceSpec> {
    Ok(s.parse()?)
}

/// Runs the server until Ctrl-C.
pub async fn run(args: ServeArgs) -> anyhow::Result<()> {
    let cfg = resolve(&args)?;
    let fd = crate::limits::raise_fd_limit();
    let handle = crate::start(cfg.clone()).await?;
    let addr = handle.local_addr();
    println!("rigcast {} listening", env!("CARGO_PKG_VERSION"));
    println!("  stream: ws://{addr}/v1/stream");
    println!("  status: http://{addr}/v1/status");
    println!("  viewer: http://{addr}/");
    print_access(&handle, fd);
    for s in handle.state().subjects().iter() {
        let info = s.info();
        let from = match s.source_kind {
            None => format!(", retargeted from {:?}", s.inputs),
            Some(kind) => format!(", {kind}"),
        };
        let listen = s
            .listen_addr
            .map(|a| format!(", listening on udp {a}"))
            .unwrap_or_default();
        println!(
            "  subject {}: {} ({} bones{from}{listen})",
            info.id, info.name, info.num_bones
        );
    }
    if let Some(r) = &cfg.record {
        println!("  recording: {}", r.display());
    }
    for v in &cfg.vmc_out {
        println!("  vmc out: {v}");
    }
    for s in &cfg.sources {
        if let SourceSpec::Vmc(vmc) = s {
            if vmc.open_to_network() {
                println!(
                    "  warning: VMC input on {} accepts datagrams from any host that can reach it; \
                     list trusted senders in allowed_senders",
                    vmc.bind
                );
            }
        }
    }
    tokio::signal::ctrl_c()
        .await
        .context("waiting for Ctrl-C")?;
    println!("rigcast: shutting down");
    handle.shutdown().await;
    Ok(())
}

/// Prints the access rules in force: the token (only when just created, or with a
/// network-facing listener that cannot be used without it), the connection cap.
fn print_access(handle: &crate::ServerHandle, fd: Option<crate::limits::FdLimit>) {
    let addr = handle.local_addr();
    let info = handle.token_info();
    let scope = handle.state().policy.scope();
    let secret = info.token.reveal();
    let location = info
        .path
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "memory (this run only)".into());
    if scope == BindScope::Network {
        println!(
            "  warning: listening on {addr}, beyond loopback: every client needs the control token, \
             streaming and status included (traffic is not encrypted)"
        );
    }
    if info.created {
        println!("  control token created in {location}");
        println!("  viewer with control: http://{addr}/?token={secret}");
    } else {
        println!(
            "  control token: in {location} (`rigcast token show` prints it and the viewer link)"
        );
    }
    let state = handle.state();
    let fd_text = match fd {
        Some(l) => match l.raised_from {
            Some(old) => format!("open-file limit raised from {old} to {}", l.soft),
            None => format!("open-file limit {}", l.soft),
        },
        None => "open-file limit unknown".into(),
    };
    println!(
        "  connections: at most {} ({fd_text})",
        state.connections.max()
    );
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
            matches!(&cfg.sources[0], SourceSpec::ReplayFile(crate::config::ReplayFileSpec { path, .. }) if path == &PathBuf::from("a.bvh"))
        );
        assert!(parse_source("webcam").is_err());
        assert!(matches!(
            parse_source("vmc:39540").unwrap(),
            SourceSpec::Vmc(crate::config::VmcSpec { port: 39540, .. })
        ));
        assert!(parse_source("vmc:x").is_err());
        assert!(matches!(
            parse_source("vmc:39540").unwrap(),
            SourceSpec::Vmc(crate::config::VmcSpec { bind, .. }) if bind.is_loopback()
        ));
        assert!(matches!(
            parse_source("vmc:0.0.0.0:39541").unwrap(),
            SourceSpec::Vmc(crate::config::VmcSpec { bind, port: 39541, .. }) if bind.is_unspecified()
        ));
        assert!(matches!(
            parse_source("webcam:2").unwrap(),
            SourceSpec::Webcam(crate::config::WebcamSpec { index: 2, .. })
        ));
        assert!(parse_source("webcam:front").is_err());
        assert!(matches!(
            parse_source("serial:suit.toml").unwrap(),
            SourceSpec::Serial(crate::config::SerialSpec { .. })
        ));
        let bad_rate = ServeArgs {
            rate: Some(0.5),
            ..ServeArgs::default()
        };
        assert!(resolve(&bad_rate).is_err());
    }
}
