//! VMC/OSC input on a UDP port (`kind = "vmc"`, `--source vmc:PORT` / `vmc:ADDR:PORT`).

use std::net::{IpAddr, Ipv4Addr, SocketAddr};

use anyhow::Context;
use rigcast_protocol::SourceKind;
use rigcast_sources::live::LiveSource;
use rigcast_sources::vmc_in::{VmcConfig, VmcSource, DEFAULT_VMC_PORT};
use serde::Deserialize;

use super::{CliError, KindSpec, Loaded, Opened};
use crate::config_error::ConfigError;

/// VMC input listens on loopback unless told otherwise: a performer's skeleton must not be
/// replaceable by any host on the network.
pub const DEFAULT_VMC_BIND: IpAddr = IpAddr::V4(Ipv4Addr::LOCALHOST);

const VMC_GRAMMAR: &str = "vmc:PORT (loopback) or vmc:ADDR:PORT with a UDP port 0..=65535";

/// A VMC/OSC listener (port 0 picks a free one).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VmcSpec {
    /// UDP port (default 39539).
    #[serde(default = "vmc_port")]
    pub port: u16,
    /// Address to listen on ([`DEFAULT_VMC_BIND`] unless configured).
    #[serde(default = "loopback")]
    pub bind: IpAddr,
    /// Sender IP addresses accepted (empty: any that can reach `bind`).
    #[serde(default)]
    pub allowed_senders: Vec<IpAddr>,
    /// Silence before the source counts as lost (default 0.5 s).
    pub lost_after_secs: Option<f32>,
    /// Subject name (default `vmc:PORT`).
    pub name: Option<String>,
}

fn vmc_port() -> u16 {
    DEFAULT_VMC_PORT
}

fn loopback() -> IpAddr {
    DEFAULT_VMC_BIND
}

impl VmcSpec {
    /// Listens on loopback `port`, any local sender, default loss timeout, default name.
    pub fn loopback(port: u16) -> VmcSpec {
        VmcSpec {
            port,
            bind: DEFAULT_VMC_BIND,
            allowed_senders: Vec::new(),
            lost_after_secs: None,
            name: None,
        }
    }

    /// Bound beyond loopback with no sender list: any host that can reach it may drive it.
    pub fn open_to_network(&self) -> bool {
        !self.bind.is_loopback() && self.allowed_senders.is_empty()
    }
}

impl KindSpec for VmcSpec {
    const KIND: SourceKind = SourceKind::Vmc;
    const CLI: Option<&'static str> = Some("vmc");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        let (bind, port) = match arg.parse::<u16>() {
            Ok(port) => (DEFAULT_VMC_BIND, port),
            Err(_) => {
                let addr: SocketAddr = arg.parse().map_err(|_| CliError::Expected(VMC_GRAMMAR))?;
                (addr.ip(), addr.port())
            }
        };
        Ok(VmcSpec {
            bind,
            ..VmcSpec::loopback(port)
        })
    }

    fn to_cli(&self) -> Option<String> {
        let says_all = self.allowed_senders.is_empty()
            && self.lost_after_secs.is_none()
            && self.name.is_none();
        says_all.then(|| {
            if self.bind == DEFAULT_VMC_BIND {
                format!("vmc:{}", self.port)
            } else {
                format!("vmc:{}", SocketAddr::new(self.bind, self.port))
            }
        })
    }

    fn validate(&self) -> Result<(), ConfigError> {
        match self.lost_after_secs {
            Some(l) if !(l.is_finite() && l > 0.0) => Err(ConfigError::Invalid {
                field: "lost_after_secs",
                message: format!("{l} must be a positive number of seconds"),
            }),
            _ => Ok(()),
        }
    }

    fn open(self) -> anyhow::Result<Opened> {
        let mut cfg = VmcConfig::port(self.port);
        cfg.bind = self.bind;
        cfg.allowed_senders = self.allowed_senders;
        if let Some(l) = self.lost_after_secs {
            cfg.lost_after_secs = l;
        }
        let (bind, port) = (cfg.bind, cfg.port);
        let source = VmcSource::bind(cfg)
            .with_context(|| format!("cannot listen for VMC on UDP {bind} port {port}"))?;
        let listen = source.local_addr();
        let name = self
            .name
            .unwrap_or_else(|| format!("vmc:{}", listen.map(|a| a.port()).unwrap_or(port)));
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
}
