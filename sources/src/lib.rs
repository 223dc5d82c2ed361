//! # rigcast-sources — where poses come from
//!
//! Files and live inputs each yield poses on their own *source skeleton*; nothing here maps
//! them onto a character (that is `rigcast-retarget`'s job).
//!
//! ```text
//!   .bvh ──bvh::read_bvh──┐
//!   .gltf/.glb/.vrm ──────┼──▶ Clip (Skeleton + poses, metres, +Y up) ──▶ Replay::sample
//!   .rcr recording ───────┘        ▲                                       (wall clock → pose)
//!                                  │ load_clip / save_clip dispatch on the extension
//!   live capture ──RecordingWriter──▶ .rcr ──RecordingReader──▶ Record stream
//!                                              (skeletons, frames, raw packets)
//! ```
//!
//! Every reader returns a [`SourceError`] naming the line (text) or byte offset (binary) and
//! what was expected; no input makes it panic.
#![warn(missing_docs)]

pub mod bvh;
pub mod demo;
pub mod error;
mod files;
pub mod gltf;
pub mod info;
pub mod live;
pub mod recording;
pub mod replay;
pub mod serial;
pub mod stature;
#[cfg(feature = "vision")]
pub mod vision;
pub mod vmc_in;

pub use demo::embedded_demo;
pub use error::SourceError;
pub use files::{
    load_clip, load_clip_and_humanoid, load_clip_with, load_rig, save_clip, save_clip_onto,
    LoadOptions, LoadedClip, RigLayout,
};
pub use info::{describe, describe_with, FileInfo};
pub use replay::{Replay, ReplayOptions};
