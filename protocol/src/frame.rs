//! The binary pose frame: one subject's pose at one tick, sent as a WebSocket binary message.
//!
//! Little-endian, fixed layout (see `PROTOCOL.md`). Two versions share the first 44 bytes:
//!
//! ```text
//! off size field
//!   0   4  magic "RGCF"
//!   4   2  u16 frame version (1 or 2)
//!   6   2  u16 flags (0)
//!   8   4  u32 subject id
//!  12   4  u32 num_bones (n)
//!  16   8  u64 seq                 per-subject, +1 per produced source frame
//!  24   8  u64 capture_nanos       Unix epoch ns, when the pose was captured
//!  32   8  u64 send_nanos          Unix epoch ns, when the server encoded the frame
//!  40   4  u32 missed_frames       frames this client missed since its previous frame
//! version 1:
//!  44   4  u32 reserved (0)
//!  48  12  3 × f32 translation of bone 0 (metres, right-handed, +Y up)
//!  60 16n  n × (x, y, z, w) f32 local rotations, bone order of the `skeleton` message
//! version 2:
//!  44   4  u32 num_translations (m)
//!  48 16n  n × (x, y, z, w) f32 local rotations
//!  48+16n 12m  m × (x, y, z) f32 local translations of the bones the `skeleton` message marks
//!          `translated`, in bone order
//! ```
//!
//! Version 1 carries only bone 0's translation, which loses the hips' motion on rigs whose
//! hips are not bone 0 (a ground root above the pelvis, most game rigs); version 2 carries the
//! translation of every bone that moves. [`encode_frame`] / [`append_frame_v2`] write into a
//! caller-owned `Vec` that is reused, so steady-state encoding allocates nothing.
//! [`decode_frame_into`] (version 1) and [`decode_any_into`] (both) validate every field and
//! fill reused buffers.

use glam::{Quat, Vec3};
use thiserror::Error;

use crate::PROTOCOL_VERSION;

/// The first four bytes of every frame.
pub const FRAME_MAGIC: [u8; 4] = *b"RGCF";
/// Size of the fixed part before the rotations (version 1).
pub const FRAME_HEADER_BYTES: usize = 60;
/// Size of the fixed part before the rotations (version 2).
pub const FRAME_V2_HEADER_BYTES: usize = 48;
/// Bytes per translated bone (version 2).
pub const BYTES_PER_TRANSLATION: usize = 12;
/// The frame version that carries translations of every moving bone.
pub const FRAME_VERSION_2: u16 = 2;
/// Bytes per bone rotation.
pub const BYTES_PER_BONE: usize = 16;
/// Offset of the `missed_frames` field, patched per client after a lag.
pub const MISSED_FRAMES_OFFSET: usize = 40;

/// Total size of a version 1 frame carrying `num_bones` rotations.
pub const fn frame_len(num_bones: usize) -> usize {
    FRAME_HEADER_BYTES + BYTES_PER_BONE * num_bones
}

/// Total size of a version 2 frame with `num_bones` rotations and `num_translations`
/// translations.
pub const fn frame_len_v2(num_bones: usize, num_translations: usize) -> usize {
    FRAME_V2_HEADER_BYTES + BYTES_PER_BONE * num_bones + BYTES_PER_TRANSLATION * num_translations
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
    /// The byte length does not match `num_bones` (and, in version 2, `num_translations`).
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
    put_common_header(out, PROTOCOL_VERSION, header, rotations.len());
    out.extend_from_slice(&0u32.to_le_bytes());
    put_floats(out, &root.to_array());
    for q in rotations {
        put_floats(out, &q.to_array());
    }
}

/// Appends a version 2 frame to `out` (not cleared, so a v1 and a v2 encoding of the same
/// pose can share one buffer): every rotation, then `translations[b]` for each bone `b` of
/// `translated` (ascending bone indices, as the `skeleton` message lists them). Indices out of
/// range are written as zero vectors rather than panicking; callers derive both from the same
/// skeleton.
pub fn append_frame_v2(
    out: &mut Vec<u8>,
    header: &FrameHeader,
    rotations: &[Quat],
    translations: &[Vec3],
    translated: &[u16],
) {
    out.reserve(frame_len_v2(rotations.len(), translated.len()));
    put_common_header(out, FRAME_VERSION_2, header, rotations.len());
    out.extend_from_slice(&(translated.len() as u32).to_le_bytes());
    for q in rotations {
        put_floats(out, &q.to_array());
    }
    for &b in translated {
        let t = translations.get(b as usize).copied().unwrap_or(Vec3::ZERO);
        put_floats(out, &t.to_array());
    }
}

/// The 44 bytes both versions share.
fn put_common_header(out: &mut Vec<u8>, version: u16, header: &FrameHeader, num_bones: usize) {
    out.extend_from_slice(&FRAME_MAGIC);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&header.flags.to_le_bytes());
    out.extend_from_slice(&header.subject.to_le_bytes());
    out.extend_from_slice(&(num_bones as u32).to_le_bytes());
    out.extend_from_slice(&header.seq.to_le_bytes());
    out.extend_from_slice(&header.capture_nanos.to_le_bytes());
    out.extend_from_slice(&header.send_nanos.to_le_bytes());
    out.extend_from_slice(&header.missed_frames.to_le_bytes());
}

fn put_floats(out: &mut Vec<u8>, values: &[f32]) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Overwrites the `missed_frames` field of an encoded frame (used to personalise a shared
/// frame for a client that lagged). Does nothing if `frame` is too short.
pub fn set_missed_frames(frame: &mut [u8], missed: u32) {
    if let Some(field) = frame.get_mut(MISSED_FRAMES_OFFSET..MISSED_FRAMES_OFFSET + 4) {
        field.copy_from_slice(&missed.to_le_bytes());
    }
}

/// The shape of a frame as its header declares it (after the length check).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameShape {
    /// Frame version (1 or 2).
    pub version: u16,
    /// Rotations carried.
    pub num_bones: u32,
    /// Translations carried (version 1: always 1, bone 0's).
    pub num_translations: u32,
}

impl FrameShape {
    fn rotations_at(&self) -> usize {
        if self.version == PROTOCOL_VERSION {
            FRAME_HEADER_BYTES
        } else {
            FRAME_V2_HEADER_BYTES
        }
    }
}

/// Reads only the header (for routing), checking magic, version and length. Accepts both
/// frame versions; the returned shape tells which.
pub fn decode_header_any(bytes: &[u8]) -> Result<(FrameHeader, FrameShape), FrameError> {
    // Both versions need at least 48 bytes; version 1 needs 60 (checked below).
    if bytes.len() < FRAME_V2_HEADER_BYTES {
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
    let num_bones = u32_at(bytes, 12);
    let (num_translations, expected_len) = match version {
        PROTOCOL_VERSION => {
            if bytes.len() < FRAME_HEADER_BYTES {
                return Err(FrameError::ShortBuffer {
                    len: bytes.len(),
                    needed: FRAME_HEADER_BYTES,
                });
            }
            (1, frame_len(num_bones as usize))
        }
        FRAME_VERSION_2 => {
            let m = u32_at(bytes, 44);
            (m, frame_len_v2(num_bones as usize, m as usize))
        }
        _ => {
            return Err(FrameError::UnsupportedVersion {
                version,
                supported: FRAME_VERSION_2,
            })
        }
    };
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
    let shape = FrameShape {
        version,
        num_bones,
        num_translations,
    };
    Ok((header, shape))
}

/// Reads only the header of a version 1 frame, checking magic, version and length.
pub fn decode_header(bytes: &[u8]) -> Result<(FrameHeader, u32), FrameError> {
    let (header, shape) = decode_header_any(bytes)?;
    if shape.version != PROTOCOL_VERSION {
        return Err(FrameError::UnsupportedVersion {
            version: shape.version,
            supported: PROTOCOL_VERSION,
        });
    }
    Ok((header, shape.num_bones))
}

/// Decodes a version 1 frame, replacing the contents of `rotations` (reused: no allocation
/// once it has grown). Returns the header and the root translation.
pub fn decode_frame_into(
    bytes: &[u8],
    rotations: &mut Vec<Quat>,
) -> Result<(FrameHeader, Vec3), FrameError> {
    let (header, _) = decode_header(bytes)?;
    let root = Vec3::new(
        finite_at(bytes, 48)?,
        finite_at(bytes, 52)?,
        finite_at(bytes, 56)?,
    );
    read_rotations(bytes, FRAME_HEADER_BYTES, rotations)?;
    Ok((header, root))
}

/// Decodes a frame of either version into reused buffers: `rotations` gets every bone's
/// rotation, `translations` the carried translations (version 1: bone 0's; version 2: one per
/// bone the `skeleton` message marks `translated`, in bone order).
pub fn decode_any_into(
    bytes: &[u8],
    rotations: &mut Vec<Quat>,
    translations: &mut Vec<Vec3>,
) -> Result<(FrameHeader, FrameShape), FrameError> {
    let (header, shape) = decode_header_any(bytes)?;
    let rot_at = shape.rotations_at();
    read_rotations(bytes, rot_at, rotations)?;
    let trans_at = if shape.version == PROTOCOL_VERSION {
        48
    } else {
        rot_at + BYTES_PER_BONE * shape.num_bones as usize
    };
    translations.clear();
    translations.reserve(shape.num_translations as usize);
    for k in 0..shape.num_translations as usize {
        let o = trans_at + BYTES_PER_TRANSLATION * k;
        translations.push(Vec3::new(
            finite_at(bytes, o)?,
            finite_at(bytes, o + 4)?,
            finite_at(bytes, o + 8)?,
        ));
    }
    Ok((header, shape))
}

fn read_rotations(bytes: &[u8], at: usize, rotations: &mut Vec<Quat>) -> Result<(), FrameError> {
    let num_bones = u32_at(bytes, 12) as usize;
    rotations.clear();
    rotations.reserve(num_bones);
    let body = &bytes[at..at + BYTES_PER_BONE * num_bones];
    for (i, chunk) in body.chunks_exact(BYTES_PER_BONE).enumerate() {
        let f = |k: usize| f32::from_le_bytes([chunk[k], chunk[k + 1], chunk[k + 2], chunk[k + 3]]);
        let q = Quat::from_xyzw(f(0), f(4), f(8), f(12));
        if !q.is_finite() {
            // Slow path only on bad input: find the offending float for the error.
            let base = at + BYTES_PER_BONE * i;
            for k in 0..4 {
                finite_at(bytes, base + 4 * k)?;
            }
        }
        rotations.push(q);
    }
    Ok(())
}

/// A decoded frame with owned buffers (convenient for tests and tools).
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedFrame {
    /// Scalar fields.
    pub header: FrameHeader,
    /// Frame version (1 or 2).
    pub version: u16,
    /// Bone 0's translation in version 1; in version 2 the first carried translation (the
    /// first `translated` bone, normally the root), or zero when none is carried.
    pub root: Vec3,
    /// Local rotations.
    pub rotations: Vec<Quat>,
    /// Carried translations (see [`decode_any_into`]).
    pub translations: Vec<Vec3>,
}

/// Decodes a frame of either version into owned buffers.
pub fn decode_frame(bytes: &[u8]) -> Result<DecodedFrame, FrameError> {
    let mut rotations = Vec::new();
    let mut translations = Vec::new();
    let (header, shape) = decode_any_into(bytes, &mut rotations, &mut translations)?;
    Ok(DecodedFrame {
        header,
        version: shape.version,
        root: translations.first().copied().unwrap_or(Vec3::ZERO),
        rotations,
        translations,
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
        version[4] = 3;
        assert_eq!(
            decode_frame(&version),
            Err(FrameError::UnsupportedVersion {
                version: 3,
                supported: 2
            })
        );
        // A version 2 frame is not a version 1 frame for the v1-only decoder.
        let mut v2 = Vec::new();
        append_frame_v2(&mut v2, &h, &rots, &[root], &[0]);
        assert!(matches!(
            decode_frame_into(&v2, &mut Vec::new()),
            Err(FrameError::UnsupportedVersion { version: 2, .. })
        ));
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

    fn v2_sample() -> (FrameHeader, Vec<Quat>, Vec<Vec3>, Vec<u16>) {
        let (h, _, rots) = sample();
        let trans = (0..5)
            .map(|i| Vec3::new(i as f32, 0.5 * i as f32, -0.25))
            .collect();
        (h, rots, trans, vec![0, 1, 4])
    }

    #[test]
    fn v2_round_trip_carries_the_marked_translations() {
        let (h, rots, trans, marked) = v2_sample();
        let mut buf = Vec::new();
        append_frame_v2(&mut buf, &h, &rots, &trans, &marked);
        assert_eq!(buf.len(), 48 + 16 * 5 + 12 * 3);
        assert_eq!(buf[4..6], 2u16.to_le_bytes());
        assert_eq!(buf[44..48], 3u32.to_le_bytes());
        // The first rotation starts right after the 48-byte header.
        assert_eq!(buf[48..52], rots[0].x.to_le_bytes());
        // Translations follow the rotations, in the marked bones' order.
        let at = 48 + 16 * 5 + 12 * 2;
        assert_eq!(buf[at..at + 4], trans[4].x.to_le_bytes());
        let d = decode_frame(&buf).unwrap();
        assert_eq!(d.header, h);
        assert_eq!(d.version, 2);
        assert_eq!(d.rotations, rots);
        assert_eq!(d.translations, vec![trans[0], trans[1], trans[4]]);
        assert_eq!(d.root, trans[0]);
    }

    #[test]
    fn v1_and_v2_share_one_buffer_and_the_v1_part_is_unchanged() {
        let (h, rots, trans, marked) = v2_sample();
        let mut v1 = Vec::new();
        encode_frame(&mut v1, &h, trans[0], &rots);
        let mut both = v1.clone();
        append_frame_v2(&mut both, &h, &rots, &trans, &marked);
        assert_eq!(both[..v1.len()], v1[..]);
        let d1 = decode_frame(&both[..v1.len()]).unwrap();
        assert_eq!((d1.version, d1.translations.clone()), (1, vec![trans[0]]));
        let d2 = decode_frame(&both[v1.len()..]).unwrap();
        assert_eq!(d2.translations.len(), 3);
    }

    #[test]
    fn v2_rejects_inconsistent_counts_and_non_finite_translations() {
        let (h, rots, trans, marked) = v2_sample();
        let mut good = Vec::new();
        append_frame_v2(&mut good, &h, &rots, &trans, &marked);
        let mut lying = good.clone();
        lying[44] = 4;
        assert!(matches!(
            decode_frame(&lying),
            Err(FrameError::CountMismatch { .. })
        ));
        let mut nan = good.clone();
        let last = nan.len() - 4;
        nan[last..].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            decode_frame(&nan),
            Err(FrameError::NonFinite { offset, .. }) if offset == last
        ));
        assert!(matches!(
            decode_frame(&good[..47]),
            Err(FrameError::ShortBuffer { len: 47, .. })
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
