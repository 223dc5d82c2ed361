//! `[cluster]`: the cluster section of the configuration (or `--nats` / `--site`), with its
//! checks and the NATS names derived from it. Plain data: the connection itself is `cluster`'s.

use std::time::Duration;

use serde::Deserialize;

use crate::config_error::ConfigError;

/// Longest `lost_after_secs` (a day): a finite 1e30 would be no `Duration`.
const MAX_LOST_AFTER_SECS: f64 = 86_400.0;

/// Whether `c` may stand in a site or namespace name (and so in a NATS subject token).
fn is_name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '-' || c == '_'
}

/// `[cluster]` in the config file (or `--nats` / `--site` on the command line).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterConfig {
    /// NATS servers, `nats://HOST:PORT`; the client fails over between them.
    pub servers: Vec<String>,
    /// This node's name in the deployment (letters, digits, `-`, `_`).
    pub site: String,
    /// Prefix of every NATS subject and of the KV bucket, so deployments sharing a NATS
    /// system stay apart (default `rigcast`).
    #[serde(default = "default_namespace")]
    pub namespace: String,
    /// NATS user name (with `password`).
    #[serde(default)]
    pub user: Option<String>,
    /// NATS password.
    #[serde(default)]
    pub password: Option<String>,
    /// NATS nkey seed (`SU…`), instead of a user and password.
    #[serde(default)]
    pub nkey_seed: Option<String>,
    /// Replicas of the KV bucket when this node creates it (3 on a 3-server cluster keeps the
    /// retained state through the loss of one server).
    #[serde(default = "default_replicas")]
    pub kv_replicas: usize,
    /// Silence after which a remote subject counts as lost, seconds.
    #[serde(default = "default_lost_after")]
    pub lost_after_secs: f32,
}

fn default_namespace() -> String {
    "rigcast".into()
}

fn default_replicas() -> usize {
    1
}

fn default_lost_after() -> f32 {
    0.5
}

impl ClusterConfig {
    /// A cluster config for `servers` (comma-separated list allowed) as `site`.
    pub fn new(servers: &str, site: &str) -> ClusterConfig {
        ClusterConfig {
            servers: servers
                .split(',')
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty())
                .collect(),
            site: site.to_string(),
            namespace: default_namespace(),
            user: None,
            password: None,
            nkey_seed: None,
            kv_replicas: default_replicas(),
            lost_after_secs: default_lost_after(),
        }
    }

    /// Checks names and credentials before anything connects.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let fail = |message: String| Err(ConfigError::Cluster(message));
        if self.servers.is_empty() {
            return fail("no NATS server given (servers = [\"nats://HOST:PORT\"])".into());
        }
        for (what, value) in [("site", &self.site), ("namespace", &self.namespace)] {
            if value.is_empty() || !value.chars().all(is_name_char) {
                return fail(format!(
                    "{what} {value:?} may only hold letters, digits, '-' and '_'"
                ));
            }
        }
        if self.password.is_some() != self.user.is_some() {
            return fail("user and password go together".into());
        }
        if self.nkey_seed.is_some() && self.user.is_some() {
            return fail("give either an nkey seed or a user and password, not both".into());
        }
        if !(1..=5).contains(&self.kv_replicas) {
            return fail("kv_replicas must be 1 to 5".into());
        }
        let lost_after = f64::from(self.lost_after_secs);
        if !(lost_after.is_finite() && lost_after > 0.0 && lost_after <= MAX_LOST_AFTER_SECS) {
            return fail(format!(
                "lost_after_secs must be a positive number of seconds up to {MAX_LOST_AFTER_SECS}"
            ));
        }
        Ok(())
    }

    /// The KV bucket holding every node's subject entries.
    pub fn bucket(&self) -> String {
        format!("{}_subjects", self.namespace)
    }

    /// The KV bucket of the shared mapping cache.
    pub fn mappings_bucket(&self) -> String {
        format!("{}_mappings", self.namespace)
    }

    /// The core NATS subject carrying the frames of subject `key` of `site`.
    pub fn frame_subject(&self, site: &str, key: &str) -> String {
        format!("{}.frame.{site}.{key}", self.namespace)
    }

    /// How long a remote subject may be silent before it counts as lost.
    pub fn lost_after(&self) -> Duration {
        Duration::from_secs_f32(self.lost_after_secs)
    }
}
