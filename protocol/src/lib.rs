//! # rigcast-protocol — everything rigcast puts on a wire
//!
//! Three encodings, one module each, all documented byte-for-byte in `PROTOCOL.md`:
//!
//! ```text
//!                      ┌──────── WebSocket  GET /v1/stream ────────┐
//!   server ──text────▶ │ control::ServerMessage (JSON, tagged)     │ ──▶ client
//!   server ◀─text───── │ control::ClientMessage (JSON, tagged)     │ ◀── client
//!   server ──binary──▶ │ frame: "RGCF" header + root + n × quat    │ ──▶ client
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
pub mod vmc;

pub use control::{ClientMessage, ErrorCode, ServerMessage};
pub use frame::{FrameError, FrameHeader, FRAME_HEADER_BYTES, FRAME_MAGIC};

/// Version of the WebSocket protocol (JSON messages and binary frames). Bumped on any
/// incompatible change; clients must refuse versions they do not know.
pub const PROTOCOL_VERSION: u16 = 1;
