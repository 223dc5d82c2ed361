//! # rigcast-protocol — everything rigcast puts on a wire
//!
//! Three encodings, one module each, all documented byte-for-byte in `PROTOCOL.md`:
//!
//! ```text
//!                      ┌──────── WebSocket  GET /v1/stream ────────┐
//!   server ──text────▶ │ control::ServerMessage (JSON, tagged)     │ ──▶ client
//!   server ◀─text───── │ control::ClientMessage (JSON, tagged)     │ ◀── client
//!   server ──binary──▶ │ frame: "RGCF" header + n × quat + moves   │ ──▶ client
//!                      └───────────────────────────────────────────┘
//!   server ──UDP─────▶   vmc: OSC bundles (/VMC/Ext/...) ≤ 1500 B    ──▶ VMC receivers
//! ```
//!
//! * [`control`]: JSON control messages (`hello`, `skeleton`, `mapping`, `lagged`, `pong`,
//!   `error`, … and client requests `subscribe`, `ping`, `set_mapping`), with a parser that
//!   classifies bad input into an [`control::ErrorCode`] so the server can answer it.
//! * [`frame`]: the fixed-layout little-endian binary pose frame. Encoding writes into a
//!   caller-owned `Vec` (no allocation once it has grown); decoding validates everything.
//! * [`coords`]: conversions between the internal space (right-handed, +Y up, metres) and
//!   Unity (left-handed, +Y up) and Blender (right-handed, +Z up). One function per direction.
//! * [`vmc`]: a VMC (OSC over UDP) encoder that packs a pose into size-capped bundles without
//!   allocating in steady state, and a tolerant decoder for VMC input.
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used))]

pub mod control;
pub mod coords;
pub mod frame;
pub mod stage_times;
pub mod status;
pub mod vmc;

pub use control::{
    ClientMessage, ErrorCode, FootState, ServerMessage, SourceKind, SourceState, TargetHealth,
    TargetMotion,
};
pub use frame::{FrameError, FrameHeader, FRAME_HEADER_BYTES, FRAME_MAGIC};

/// The protocol version every session starts in (JSON messages and version 1 binary frames),
/// so clients written for version 1 keep working unchanged.
pub const PROTOCOL_VERSION: u16 = 1;

/// Every protocol version the server speaks. A client switches with `set_protocol`; version 2
/// differs only in the binary frame (translations of every moving bone, see [`frame`]).
pub const PROTOCOL_VERSIONS: [u16; 2] = [1, 2];
