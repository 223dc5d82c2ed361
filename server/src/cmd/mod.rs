//! Subcommand implementations, one module each (wired up in [`crate::cli::Command`]).

pub mod bench;
pub mod calibrate;
pub mod convert;
pub mod devices;
pub mod graft;
pub mod graph;
pub mod info;
pub mod loadtest;
pub mod map;
pub mod pose;
pub mod record;
pub mod retarget;
pub mod serve;
pub mod setup;
pub mod token;
pub mod unit;
