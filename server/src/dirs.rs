//! Where rigcast keeps per-user files, after the XDG base directory convention: caches under
//! `$XDG_CACHE_HOME` (else `~/.cache`), settings such as the control token under
//! `$XDG_CONFIG_HOME` (else `~/.config`). An empty variable counts as unset, as the convention
//! says.

use std::path::PathBuf;

/// Which base directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UserBase {
    /// `$XDG_CACHE_HOME`, else `~/.cache`: files rigcast can rebuild.
    Cache,
    /// `$XDG_CONFIG_HOME`, else `~/.config`: files the user keeps.
    Config,
}

impl UserBase {
    fn variable_and_fallback(self) -> (&'static str, &'static str) {
        match self {
            UserBase::Cache => ("XDG_CACHE_HOME", ".cache"),
            UserBase::Config => ("XDG_CONFIG_HOME", ".config"),
        }
    }
}

/// `BASE/rigcast/NAME`; `None` when neither the variable nor `HOME` is set.
pub fn rigcast_dir(base: UserBase, name: &str) -> Option<PathBuf> {
    let (variable, fallback) = base.variable_and_fallback();
    let base = std::env::var_os(variable)
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(fallback)))?;
    Some(base.join("rigcast").join(name))
}
