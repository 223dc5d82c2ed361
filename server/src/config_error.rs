//! The one error type of the configuration: the file, the flags and every section's checks
//! (sources, performers, limits, `[cluster]`). A module of its own so that the schema's parts
//! (`config`, `source_kinds`, `cluster_config`) report in it without depending on each other.

use std::path::PathBuf;

use thiserror::Error;

/// Errors in the configuration file or flags.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read config {path}: {source}")]
    Read {
        /// the file
        path: PathBuf,
        /// the IO error
        source: std::io::Error,
    },
    /// The file is not valid TOML for this schema.
    #[error("invalid config {path}: {source}")]
    Parse {
        /// the file
        path: PathBuf,
        /// the TOML error (with line and column)
        source: toml::de::Error,
    },
    /// A `--source` argument of no known kind.
    #[error(
        "unknown source {text:?}; expected replay:FILE, vmc:PORT, serial:CONFIG.toml, video:FILE, webcam:INDEX or demo"
    )]
    UnknownSource {
        /// the argument
        text: String,
    },
    /// A `--source` argument of a known kind whose argument is malformed.
    #[error("--source {text:?}: expected {expected}")]
    BadSourceArg {
        /// the argument
        text: String,
        /// the grammar of its kind
        expected: &'static str,
    },
    /// `[cluster]` (or `--nats` / `--site`) is incomplete or malformed.
    #[error("cluster: {0}")]
    Cluster(String),
    /// A value is out of range or malformed.
    #[error("invalid {field}: {message}")]
    Invalid {
        /// which setting
        field: &'static str,
        /// what is wrong
        message: String,
    },
}
