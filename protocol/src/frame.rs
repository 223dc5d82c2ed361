//! The binary pose frame: one subject's pose at one tick, sent as a WebSocket binary message.
//!
//! Little-endian, fixed layout (see `PROTOCOL.md`):
//!
//! ```text
//! off size field
//!   0   4  magic "RGCF"
//!   4   2  u16 protocol version (1)
//!   6   2  u16 flags (0)
//!   8   4  u32 subject id
//!  12   4  u32 num_bones (n)
//!  16   8  u64 seq                 per-subject, +1 per produced source frame
//!  24   8  u64 capture_nanos       Unix epoch ns, when the pose was captured
//!  32   8  u64 send_nanos          Unix epoch ns, when the server encoded the frame
//!  40   4  u32 missed_frames       frames this client missed since its previous frame
//!  44   4  u32 reserved (0)
//!  48  12  3 × f32 root translation (metres, right-handed, +Y up)
//!  60 16n  n × (x, y, z, w) f32 local rotations, bone order of the `skeleton` message
//! ```
//!
//! [`encode_frame`] writes into a caller-owned `Vec` that is cleared and reused, so steady-state
//! encoding allocates nothing. [`decode_frame_into`] validates every field and fills a reused
//! rotation buffer.

use glam::{Quat, Vec3};
use thiserror::Error;

use crate::PROTOCOL_VERSION;

/// The first four bytes of every frame.
pub const FRAME_MAGIC: [u8; 4] = *b"RGCF";
/// Size of the fixed part before the rotations.
pub const FRAME_HEADER_BYTES: usize = 60;
/// Bytes per bone rotation.
pub const BYTES_PER_BONE: usize = 16;
/// Offset of the `missed_frames` field, patched per client after a lag.
pub const MISSED_FRAMES_OFFSET: usize = 40;

/// Total size of a frame carrying `num_bones` rotations.
pub const fn frame_len(num_bones: usize) -> usize {
    FRAME_HEADER_BYTES + BYTES_PER_BONE * num_bones
}

/// The scalar fields of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameHeader {
    /// Flags; 0 in version 1 (receivers must ignore unknown bits).
    pub flags: u16,
    /// Subject id.
    pub subject: u32,
    /// Per-subject sequence number.
    pub seq: u64,
    /// Capture time, Unix epoch nanoseconds.
    pub capture_nanos: u64,
    /// Encode time, Unix epoch nanoseconds.
    pub send_nanos: u64,
    /// Frames this client missed since its previous frame.
    pub missed_frames: u32,
}

/// Why a byte buffer is not a valid frame.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FrameError {
    /// Fewer bytes than the header (or than the header's bone count) needs.
    #[error("frame too short: {len} bytes, need at least {needed}")]
    ShortBuffer {
        /// bytes received
        len: usize,
        /// bytes needed
        needed: usize,
    },
    /// The first four bytes are not `RGCF`.
    #[error("bad magic {found:02x?} at offset 0, expected \"RGCF\"")]
    BadMagic {
        /// the bytes found
        found: [u8; 4],
    },
    /// A protocol version this decoder does not know.
    #[error("unsupported frame version {version} at offset 4, this decoder knows {supported}")]
    UnsupportedVersion {
        /// version in the frame
        version: u16,
        /// version supported
        supported: u16,
    },
    /// The byte length does not match `num_bones` (or the caller's expected count).
    #[error("bone count mismatch: header says {num_bones} bones ({expected_len} bytes), got {len} bytes")]
    CountMismatch {
        /// bones in the header
        num_bones: u32,
        /// bytes that count implies
        expected_len: usize,
        /// bytes received
        len: usize,
    },
    /// A NaN or infinite float.
    #[error("non-finite value {value} at byte offset {offset}")]
    NonFinite {
        /// offset of the float
        offset: usize,
        /// the value
        value: f32,
    },
}

/// Encodes a frame into `out` (cleared first). `out` keeps its capacity, so once it has grown
/// to the frame size, encoding allocates nothing.
pub fn encode_frame(out: &mut Vec<u8>, header: &FrameHeader, root: Vec3, rotations: &[Quat]) {
    out.clear();
    out.reserve(frame_len(rotations.len()));
    out.extend_from_slice(&FRAME_MAGIC);
    out.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    out.extend_from_slice(&header.flags.to_le_bytes());
    out.extend_from_slice(&header.subject.to_le_bytes());
    out.extend_from_slice(&(rotations.len() as u32).to_le_bytes());
    out.extend_from_slice(&header.seq.to_le_bytes());
    out.extend_from_slice(&header.capture_nanos.to_le_bytes());
    out.extend_from_slice(&header.send_nanos.to_le_bytes());
    out.extend_from_slice(&header.missed_frames.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for v in root.to_array() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for q in rotations {
        for v in q.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// Overwrites the `missed_frames` field of an encoded frame (used to personalise a shared
/// frame for a client that lagged). Does nothing if `frame` is too short.
pub fn set_missed_frames(frame: &mut [u8], missed: u32) {
    if let Some(field) = frame.get_mut(MISSED_FRAMES_OFFSET..MISSED_FRAMES_OFFSET + 4) {
        field.copy_from_slice(&missed.to_le_bytes());
    }
}

/// Reads only the header (for routing), checking magic, version and length.
pub fn decode_header(bytes: &[u8]) -> Result<(FrameHeader, u32), FrameError> {
    if bytes.len() < FRAME_HEADER_BYTES {
        return Err(FrameError::ShortBuffer {
            len: bytes.len(),
            needed: FRAME_HEADER_BYTES,
        });
    }
    let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
    if magic != FRAME_MAGIC {
        return Err(FrameError::BadMagic { found: magic });
    }
    let version = u16_at(bytes, 4);
    if version != PROTOCOL_VERSION {
        return Err(FrameError::UnsupportedVersion {
            version,
            supported: PROTOCOL_VERSION,
        });
    }
    let num_bones = u32_at(bytes, 12);
    let expected_len = frame_len(num_bones as usize);
    if bytes.len() != expected_len {
        return Err(FrameError::CountMismatch {
            num_bones,
            expected_len,
            len: bytes.len(),
        });
    }
    let header = FrameHeader {
        flags: u16_at(bytes, 6),
        subject: u32_at(bytes, 8),
        seq: u64_at(bytes, 16),
        capture_nanos: u64_at(bytes, 24),
        send_nanos: u64_at(bytes, 32),
        missed_frames: u32_at(bytes, 40),
    };
    Ok((header, num_bones))
}

/// Decodes a frame, replacing the contents of `rotations` (reused: no allocation once it has
/// grown). Returns the header and the root translation.
pub fn decode_frame_into(
    bytes: &[u8],
    rotations: &mut Vec<Quat>,
) -> Result<(FrameHeader, Vec3), FrameError> {
    let (header, num_bones) = decode_header(bytes)?;
    let root = Vec3::new(
        finite_at(bytes, 48)?,
        finite_at(bytes, 52)?,
        finite_at(bytes, 56)?,
    );
    rotations.clear();
    rotations.reserve(num_bones as usize);
    let body = &bytes[FRAME_HEADER_BYTES..];
    for (i, chunk) in body.chunks_exact(BYTES_PER_BONE).enumerate() {
        let f = |k: usize| f32::from_le_bytes([chunk[k], chunk[k + 1], chunk[k + 2], chunk[k + 3]]);
        let q = Quat::from_xyzw(f(0), f(4), f(8), f(12));
        if !q.is_finite() {
            // Slow path only on bad input: find the offending float for the error.
            let base = FRAME_HEADER_BYTES + BYTES_PER_BONE * i;
            for k in 0..4 {
                finite_at(bytes, base + 4 * k)?;
            }
        }
        rotations.push(q);
    }
    Ok((header, root))
}

/// A decoded frame with owned rotations (convenient for tests and tools).
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedFrame {
    /// Scalar fields.
    pub header: FrameHeader,
    /// Root translation.
    pub root: Vec3,
    /// Local rotations.
    pub rotations: Vec<Quat>,
}

/// Decodes a frame into owned buffers.
pub fn decode_frame(bytes: &[u8]) -> Result<DecodedFrame, FrameError> {
    let mut rotations = Vec::new();
    let (header, root) = decode_frame_into(bytes, &mut rotations)?;
    Ok(DecodedFrame {
        header,
        root,
        rotations,
    })
}

// The helpers below are only called after the length check, so the slices are in bounds.
fn u16_at(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn u64_at(b: &[u8], o: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[o..o + 8]);
    u64::from_le_bytes(a)
}
fn finite_at(b: &[u8], o: usize) -> Result<f32, FrameError> {
    let value = f32::from_bits(u32_at(b, o));
    if value.is_finite() {
        Ok(value)
    } else {
        Err(FrameError::NonFinite { offset: o, value })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> (FrameHeader, Vec3, Vec<Quat>) {
        let header = FrameHeader {
            flags: 0,
            subject: 7,
            seq: 123_456_789_012,
            capture_nanos: 1_700_000_000_123_456_789,
            send_nanos: 1_700_000_000_200_000_000,
            missed_frames: 3,
        };
        let rots = (0..5)
            .map(|i| Quat::from_rotation_y(i as f32 * 0.3) * Quat::from_rotation_x(0.1))
            .collect();
        (header, Vec3::new(0.5, 1.0, -2.0), rots)
    }

    #[test]
    fn round_trip() {
        let (h, root, rots) = sample();
        let mut buf = Vec::new();
        encode_frame(&mut buf, &h, root, &rots);
        assert_eq!(buf.len(), 60 + 16 * 5);
        let d = decode_frame(&buf).unwrap();
        assert_eq!(d.header, h);
        assert_eq!(d.root, root);
        assert_eq!(d.rotations, rots);
    }

    #[test]
    fn layout_matches_documented_offsets() {
        let (h, root, rots) = sample();
        let mut buf = Vec::new();
        encode_frame(&mut buf, &h, root, &rots);
        assert_eq!(&buf[0..4], b"RGCF");
        assert_eq!(buf[4..6], 1u16.to_le_bytes());
        assert_eq!(buf[6..8], [0, 0]);
        assert_eq!(buf[8..12], 7u32.to_le_bytes());
        assert_eq!(buf[12..16], 5u32.to_le_bytes());
        assert_eq!(buf[16..24], 123_456_789_012u64.to_le_bytes());
        assert_eq!(buf[40..44], 3u32.to_le_bytes());
        assert_eq!(buf[44..48], [0, 0, 0, 0]);
        assert_eq!(buf[48..52], 0.5f32.to_le_bytes());
        assert_eq!(buf[56..60], (-2.0f32).to_le_bytes());
        assert_eq!(buf[60 + 16 + 12..60 + 32], rots[1].w.to_le_bytes());
    }

    #[test]
    fn encode_reuses_buffer() {
        let (h, root, rots) = sample();
        let mut buf = Vec::new();
        encode_frame(&mut buf, &h, root, &rots);
        let (ptr, cap) = (buf.as_ptr(), buf.capacity());
        encode_frame(&mut buf, &h, root, &rots);
        assert_eq!((buf.as_ptr(), buf.capacity()), (ptr, cap));
    }

    #[test]
    fn set_missed_frames_patches_header() {
        let (h, root, rots) = sample();
        let mut buf = Vec::new();
        encode_frame(&mut buf, &h, root, &rots);
        set_missed_frames(&mut buf, 99);
        assert_eq!(decode_frame(&buf).unwrap().header.missed_frames, 99);
    }

    #[test]
    fn rejects_bad_frames() {
        let (h, root, rots) = sample();
        let mut good = Vec::new();
        encode_frame(&mut good, &h, root, &rots);

        assert_eq!(
            decode_frame(&good[..59]),
            Err(FrameError::ShortBuffer {
                len: 59,
                needed: 60
            })
        );
        assert!(matches!(
            decode_frame(&good[..good.len() - 1]),
            Err(FrameError::CountMismatch { num_bones: 5, .. })
        ));
        let mut longer = good.clone();
        longer.push(0);
        assert!(matches!(
            decode_frame(&longer),
            Err(FrameError::CountMismatch { .. })
        ));
        let mut magic = good.clone();
        magic[0] = b'X';
        assert!(matches!(
            decode_frame(&magic),
            Err(FrameError::BadMagic { .. })
        ));
        let mut version = good.clone();
        version[4] = 2;
        assert_eq!(
            decode_frame(&version),
            Err(FrameError::UnsupportedVersion {
                version: 2,
                supported: 1
            })
        );
        let mut count = good.clone();
        count[12] = 200;
        assert!(matches!(
            decode_frame(&count),
            Err(FrameError::CountMismatch { num_bones: 200, .. })
        ));
        let mut nan = good.clone();
        nan[64..68].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            decode_frame(&nan),
            Err(FrameError::NonFinite { offset: 64, .. })
        ));
        let mut inf = good;
        inf[52..56].copy_from_slice(&f32::INFINITY.to_le_bytes());
        assert!(matches!(
            decode_frame(&inf),
            Err(FrameError::NonFinite { offset: 52, .. })
        ));
    }

    #[test]
    fn zero_bone_frame_is_header_only() {
        let mut buf = Vec::new();
        encode_frame(&mut buf, &FrameHeader::default(), Vec3::ZERO, &[]);
        assert_eq!(buf.len(), FRAME_HEADER_BYTES);
        assert!(decode_frame(&buf).unwrap().rotations.is_empty());
    }
}
