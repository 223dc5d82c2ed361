//! # rigcast-server — the `rigcast` binary's library
//!
//! Hosts the engine (`rigcast-engine`, which does no IO) inside a tokio runtime:
//!
//! ```text
//!  SourceSpec ─load─▶ Replay task ─┐
//!  live source thread (VMC, serial, video) ─┴─▶ SourceDoor (newest pose, health)
//!  mapper thread (built mappings), sessions (set_mapping, …) ─▶ the engine's Inbox
//!                                                   │
//!                 engine loop (tick_task): sleeps until the engine's next wake-up or the
//!                 inbox's wake, drains the inbox ─▶ Engine::handle_input(Frame | Health |
//!                 Mapping | Command), reads the clocks ─▶ handle_input(Timeout)
//!                   │ its own timetable @ rate_hz; poll_output ─▶ the outputs below
//!                   │ source poses into their slots (latest wins, one per source)
//!                   │ performers: Mapping::apply into preallocated target poses
//!                   │   (mappings built by the mapper thread, which the engine asks with
//!                   │   Output::Build; never awaited by the tick)
//!                   │ encode each subject once → Bytes (shared)      VMC bundles → UDP
//!                   ▼                                                 (≤1500 B each)
//!             broadcast<OutFrame>  (bounded; never awaited by the tick) ──▶ recorder
//!                   │
//!        ┌──────────┼───────────┐
//!   client task  client task  client task   (one per WebSocket; a lagging one gets
//!        │            │            │          `lagged` + missed_frames, stays connected)
//!   GET /v1/stream  (same listener also serves GET /v1/status and the viewer's files;
//!                    every request passes the connection cap (limits.rs) and the
//!                    Origin/Host/token checks (access.rs) first)
//! ```
//!
//! [`start`] (in [`boot`]: load, assemble, spawn) runs all of it in-process (tests use `127.0.0.1:0`); the binary's subcommands live
//! in [`cmd`] and are listed in [`cli::Command`]. The engine's items are reached at their own
//! paths in `rigcast_engine`.
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used))]

pub mod access;
pub mod batched_writes;
pub mod boot;
pub mod calibration;
pub mod changes;
pub mod character;
pub mod cli;
pub mod clients;
pub mod cluster;
pub mod cluster_config;
pub mod cmd;
pub mod config;
pub mod config_error;
pub mod demo;
pub mod dirs;
pub mod fault;
pub mod graph_files;
pub mod http;
pub mod idle_graph;
pub mod limits;
pub mod live;
pub mod mapper;
pub mod mapping_store;
pub mod model;
pub mod offline;
pub mod panic_reports;
pub mod recorder;
pub mod replay_task;
pub mod skeleton_wire;
pub mod source_kinds;
pub mod state;
pub mod stats;
pub mod stream_record;
pub mod tick_task;
pub mod token;
pub mod wire;

#[cfg(test)]
#[path = "../../sources/tests/common/shared_data.rs"]
mod shared_data;

pub use boot::{start, ServerHandle};
pub use config::{
    AccessConfig, LimitsConfig, PerformerSpec, ReplaySettings, ServerConfig, SourceSpec,
    TargetSpec, VmcOut,
};
pub use source_kinds::{demo_clip, NO_WEBCAM_HINT};
pub use token::{ControlToken, TokenSetting};
