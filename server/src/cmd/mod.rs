//! Subcommand implementations, one module each (wired up in [`crate::cli::Command`]).

pub mod convert;
pub mod info;
pub mod record;
pub mod serve;
