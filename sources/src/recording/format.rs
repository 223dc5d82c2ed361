//! Record types and the constants of the `.rcr` byte layout.

use std::sync::Arc;

use rigcast_retarget::{Pose, Skeleton};

/// First 8 bytes of every recording. The high byte and CR/LF/SUB catch text-mode mangling.
pub const MAGIC: [u8; 8] = [0x89, b'R', b'C', b'R', b'\r', b'\n', 0x1a, b'\n'];
/// Major version this build writes and reads. A newer major version is rejected.
pub const FORMAT_MAJOR: u16 = 1;
/// Minor version this build writes. Minor versions only add record types or append fields.
pub const FORMAT_MINOR: u16 = 0;
/// Largest payload accepted; a bigger length prefix means a corrupt file.
pub const MAX_RECORD_BYTES: u32 = 64 << 20;

pub(crate) const HEADER_BYTES: usize = 16;
pub(crate) const RECORD_HEADER_BYTES: usize = 5;
pub(crate) const TYPE_SKELETON: u8 = 0x01;
pub(crate) const TYPE_FRAME: u8 = 0x02;
pub(crate) const TYPE_RAW: u8 = 0x03;
pub(crate) const TYPE_END: u8 = 0x7f;
pub(crate) const FLAG_TRANSLATIONS: u8 = 0x01;
pub(crate) const NO_PARENT: u32 = u32::MAX;

/// A skeleton announcement: frames of `subject_id` that follow use it.
#[derive(Debug, Clone, PartialEq)]
pub struct SkeletonRecord {
    /// The subject (performer / source) this skeleton belongs to.
    pub subject_id: u32,
    /// Display name of the subject.
    pub name: String,
    /// The skeleton.
    pub skeleton: Arc<Skeleton>,
}

/// One pose of one subject.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// The subject; its skeleton record precedes this frame.
    pub subject_id: u32,
    /// Per-subject sequence number.
    pub seq: u64,
    /// Capture time, nanoseconds (Unix epoch for live captures, from 0 for generated clips).
    pub capture_nanos: u64,
    /// The pose on the subject's skeleton.
    pub pose: Pose,
}

/// What produced a raw input packet, so it can be replayed through the matching parser.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RawKind {
    /// One OSC datagram (packet or bundle), e.g. VMC.
    Osc,
    /// A chunk of bytes read from a serial port.
    Serial,
    /// Pose-estimation landmarks.
    Landmarks,
    /// Anything else.
    Other,
}

impl RawKind {
    pub(crate) fn code(self) -> u8 {
        match self {
            RawKind::Osc => 0,
            RawKind::Serial => 1,
            RawKind::Landmarks => 2,
            RawKind::Other => 255,
        }
    }

    pub(crate) fn from_code(code: u8) -> RawKind {
        match code {
            0 => RawKind::Osc,
            1 => RawKind::Serial,
            2 => RawKind::Landmarks,
            // Kinds added by later minor versions read as Other rather than failing.
            _ => RawKind::Other,
        }
    }
}

/// Raw input bytes as received from a live source.
#[derive(Debug, Clone, PartialEq)]
pub struct RawPacket {
    /// The live source that received them.
    pub source_id: u32,
    /// What kind of bytes they are.
    pub kind: RawKind,
    /// Receive time, nanoseconds.
    pub capture_nanos: u64,
    /// The bytes, unchanged.
    pub bytes: Vec<u8>,
}

/// One record of a recording.
#[derive(Debug, Clone, PartialEq)]
pub enum Record {
    /// A subject's skeleton.
    Skeleton(SkeletonRecord),
    /// A subject's pose.
    Frame(FrameRecord),
    /// Raw input bytes.
    Raw(RawPacket),
    /// The writer finished cleanly.
    End,
}
