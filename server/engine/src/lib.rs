//! # rigcast-engine — the realtime engine, with no IO
//!
//! Subjects (the streamed poses and what is derived from their skeletons), performers
//! (sources' poses → mapping → foot lock / fallback → a target's pose), live grafts, idle
//! graphs, and the tick that encodes every subject's frame and VMC bundles. The engine reads
//! no clock (the host passes each tick its [`clock::TickTime`]), opens no socket or file and
//! runs no async runtime: the host crate (`rigcast-server`) owns the threads, tasks, channels
//! and sockets and hands the engine plain values.
//!
//! ```text
//!  source threads ─SourceDoor─▶ ┐
//!  mapper, sessions ─────────────┴▶ Inbox ─drain─▶ host loop
//!  host loop ─handle_input(Timeout(time) | Frame | Health | Mapping | Command)─▶ Engine
//!    ▲                                   timetable (schedule) · Ticker · foot plants · status
//!    └─poll_output(): Datagram · Frame · Event · Build · Ticked · Timeout(next wake-up)
//!  Engine ─FrameWriter─▶ source subjects' slots ◀─FrameReader─ the tick's performers, encoding
//! ```
//!
//! Entry points: [`Engine`] (fed [`Input`]s, yielding [`Output`]s and its next wake-up),
//! [`inbox::Inbox`] (where the host's threads leave inputs for the engine's loop),
//! [`Ticker`] (one tick at a given time, its outputs to a [`TickOutput`]),
//! [`subject::Subject`], [`performer::Performer`], [`footplants::FootplantSampler`],
//! [`fault::announce`]. `server/tests/engine_machine.rs` drives the engine on a simulated
//! clock as the host does.
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used))]

pub mod builtin;
pub mod clock;
pub mod error;
pub mod events;
pub mod fault;
pub mod footplants;
pub mod graft_live;
pub mod idle_graph;
pub mod inbox;
pub mod machine;
pub mod performer;
pub mod reports;
pub mod schedule;
pub mod settings;
pub mod slot;
pub mod stats;
pub mod status;
pub mod subject;
pub mod subject_list;
pub mod tick;
pub mod translated;
pub mod vmc_pose;

pub use clock::TickTime;
pub use machine::{Engine, EngineParts, Input, Output};
pub use tick::{OutFrame, TickContext, TickOutput, Ticker};
