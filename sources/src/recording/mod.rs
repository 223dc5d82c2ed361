//! rigcast recordings (`.rcr`): a streaming, versioned binary log of skeletons, frames and raw
//! input packets. The byte layout is documented in `recordings/FORMAT.md`.
//!
//! ```text
//!  header(16) │ rec │ rec │ rec │ … │ end
//!  rec = type:u8 │ len:u32 │ payload[len]      (little-endian throughout)
//! ```
//!
//! Length prefixes let readers skip record types they do not know (same major version) and
//! detect a truncated tail (a crash while recording) without losing earlier records.

mod clip;
mod format;
mod reader;
mod writer;

pub use clip::{clip_from_recording, write_clip_recording};
pub use format::{
    FrameRecord, RawKind, RawPacket, Record, SkeletonRecord, FORMAT_MAJOR, FORMAT_MINOR, MAGIC,
    MAX_RECORD_BYTES,
};
pub use reader::{read_recording, Recording, RecordingReader};
pub use writer::RecordingWriter;

#[cfg(test)]
mod tests;
