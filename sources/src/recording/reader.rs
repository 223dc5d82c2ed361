//! Streaming recording reader.

use std::collections::HashMap;
use std::io::Read;
use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_retarget::{Pose, RawSkeleton, Skeleton, Transform};

use super::format::*;
use crate::error::SourceError;

/// Reads records one by one: an iterator of `Result<Record, SourceError>`. After an error the
/// iterator ends; records before it were already yielded, so a truncated tail never loses
/// earlier data. Unknown record types of the same major version are skipped and counted.
pub struct RecordingReader<R: Read> {
    input: R,
    offset: u64,
    minor: u16,
    skeletons: HashMap<u32, Arc<Skeleton>>,
    pub(super) payload: Vec<u8>,
    finished: bool,
    ended_cleanly: bool,
    skipped_records: usize,
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
fn read_up_to(input: &mut impl Read, buf: &mut [u8]) -> Result<usize, SourceError> {
    let mut n = 0;
    while n < buf.len() {
        match input.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(SourceError::Stream(e)),
        }
    }
    Ok(n)
}

impl<R: Read> RecordingReader<R> {
    /// Reads and checks the header.
    pub fn new(mut input: R) -> Result<Self, SourceError> {
        let mut header = [0u8; HEADER_BYTES];
        let n = read_up_to(&mut input, &mut header)?;
        if n < MAGIC.len() || header[..MAGIC.len()] != MAGIC {
            return Err(SourceError::BadMagic {
                expected: MAGIC,
                found: header[..n.min(MAGIC.len())].to_vec(),
            });
        }
        if n < HEADER_BYTES {
            return Err(SourceError::TruncatedRecord {
                offset: 0,
                expected: HEADER_BYTES as u64,
                found: n as u64,
            });
        }
        let major = u16::from_le_bytes([header[8], header[9]]);
        let minor = u16::from_le_bytes([header[10], header[11]]);
        if major != FORMAT_MAJOR {
            return Err(SourceError::UnsupportedVersion {
                found: major,
                supported: FORMAT_MAJOR,
            });
        }
        Ok(RecordingReader {
            input,
            offset: HEADER_BYTES as u64,
            minor,
            skeletons: HashMap::new(),
            payload: Vec::new(),
            finished: false,
            ended_cleanly: false,
            skipped_records: 0,
        })
    }

    /// The file's (major, minor) version.
    pub fn version(&self) -> (u16, u16) {
        (FORMAT_MAJOR, self.minor)
    }

    /// Records of unknown types skipped so far.
    pub fn skipped_records(&self) -> usize {
        self.skipped_records
    }

    /// True once the end marker has been read (false for a file cut short by a crash).
    pub fn ended_cleanly(&self) -> bool {
        self.ended_cleanly
    }

    fn next_record(&mut self) -> Result<Option<Record>, SourceError> {
        while let Some((kind, at)) = self.read_payload()? {
            match self.decode(kind, at)? {
                Some(record) => return Ok(Some(record)),
                None => self.skipped_records += 1,
            }
        }
        Ok(None)
    }

    /// Reads the next record's header and payload (into `self.payload`): its kind and where it
    /// starts, or `None` at the end of the input.
    fn read_payload(&mut self) -> Result<Option<(u8, u64)>, SourceError> {
        let at = self.offset;
        let mut head = [0u8; RECORD_HEADER_BYTES];
        let n = read_up_to(&mut self.input, &mut head)?;
        if n == 0 {
            return Ok(None);
        }
        if n < RECORD_HEADER_BYTES {
            return Err(SourceError::TruncatedRecord {
                offset: at,
                expected: RECORD_HEADER_BYTES as u64,
                found: n as u64,
            });
        }
        let len = u32::from_le_bytes([head[1], head[2], head[3], head[4]]);
        if len > MAX_RECORD_BYTES {
            return Err(SourceError::RecordTooLarge {
                offset: at,
                length: len as u64,
                max: MAX_RECORD_BYTES as u64,
            });
        }
        // `take` + `read_to_end` grows the buffer only as bytes arrive, so a corrupt length
        // on a short file cannot make us allocate the whole claimed size.
        self.payload.clear();
        let got = (&mut self.input)
            .take(len as u64)
            .read_to_end(&mut self.payload)?;
        if got < len as usize {
            return Err(SourceError::TruncatedRecord {
                offset: at,
                expected: (RECORD_HEADER_BYTES + len as usize) as u64,
                found: (RECORD_HEADER_BYTES + got) as u64,
            });
        }
        self.offset += (RECORD_HEADER_BYTES + got) as u64;
        Ok(Some((head[0], at)))
    }

    /// The record of `kind` in `self.payload` (starting at `at`), or `None` for a kind this
    /// reader does not know (a newer writer's), which is skipped.
    fn decode(&mut self, kind: u8, at: u64) -> Result<Option<Record>, SourceError> {
        let mut cur = Cursor {
            bytes: &self.payload,
            pos: 0,
            record_offset: at,
        };
        Ok(Some(match kind {
            TYPE_SKELETON => {
                let rec = decode_skeleton(&mut cur)?;
                self.skeletons.insert(rec.subject_id, rec.skeleton.clone());
                Record::Skeleton(rec)
            }
            TYPE_FRAME => Record::Frame(decode_frame(&mut cur, &self.skeletons)?),
            TYPE_RAW => {
                let source_id = cur.u32("source id")?;
                let kind = RawKind::from_code(cur.u8("raw kind")?);
                let capture_nanos = cur.u64("capture time")?;
                let bytes = cur.bytes[cur.pos..].to_vec();
                Record::Raw(RawPacket {
                    source_id,
                    kind,
                    capture_nanos,
                    bytes,
                })
            }
            TYPE_END => {
                self.ended_cleanly = true;
                Record::End
            }
            _ => return Ok(None),
        }))
    }
}

impl<R: Read> Iterator for RecordingReader<R> {
    type Item = Result<Record, SourceError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.finished {
            return None;
        }
        match self.next_record() {
            Ok(Some(Record::End)) => {
                self.finished = true;
                Some(Ok(Record::End))
            }
            Ok(Some(r)) => Some(Ok(r)),
            Ok(None) => {
                self.finished = true;
                None
            }
            Err(e) => {
                self.finished = true;
                Some(Err(e))
            }
        }
    }
}

struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    record_offset: u64,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], SourceError> {
        if self.bytes.len() - self.pos < n {
            return Err(self.bad(format!("payload ends inside the {what}")));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn bad(&self, reason: String) -> SourceError {
        SourceError::BadRecord {
            offset: self.record_offset,
            reason,
        }
    }
    fn u8(&mut self, what: &str) -> Result<u8, SourceError> {
        Ok(self.take(1, what)?[0])
    }
    fn u16(&mut self, what: &str) -> Result<u16, SourceError> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self, what: &str) -> Result<u32, SourceError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self, what: &str) -> Result<u64, SourceError> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    fn f32s<const N: usize>(&mut self, what: &str) -> Result<[f32; N], SourceError> {
        let b = self.take(4 * N, what)?;
        let mut out = [0f32; N];
        for (i, v) in out.iter_mut().enumerate() {
            *v = f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]]);
            if !v.is_finite() {
                return Err(self.bad(format!("non-finite value in the {what}")));
            }
        }
        Ok(out)
    }
    fn string(&mut self, what: &str) -> Result<String, SourceError> {
        let len = self.u16(what)? as usize;
        let b = self.take(len, what)?;
        String::from_utf8(b.to_vec()).map_err(|_| self.bad(format!("{what} is not UTF-8")))
    }
}

fn decode_skeleton(cur: &mut Cursor<'_>) -> Result<SkeletonRecord, SourceError> {
    let subject_id = cur.u32("subject id")?;
    let name = cur.string("subject name")?;
    let num_bones = cur.u32("bone count")? as usize;
    // Each bone takes at least 34 bytes; checking first bounds the allocation below.
    if num_bones.saturating_mul(34) > cur.bytes.len() - cur.pos {
        return Err(cur.bad(format!("bone count {num_bones} does not fit the record")));
    }
    let mut raw = RawSkeleton::default();
    for _ in 0..num_bones {
        let bone_name = cur.string("bone name")?;
        let parent = cur.u32("bone parent")?;
        let t = cur.f32s::<3>("rest translation")?;
        let q = cur.f32s::<4>("rest rotation")?;
        let parent = (parent != NO_PARENT).then_some(parent as usize);
        raw.add(
            bone_name,
            parent,
            Transform {
                translation: Vec3::from_array(t),
                rotation: Quat::from_array(q),
            },
        );
    }
    let skeleton = Skeleton::build(&raw).map_err(|e| cur.bad(format!("invalid skeleton: {e}")))?;
    // Frames index bones in the written order, so the order must already be depth-first.
    let same_order = skeleton
        .names()
        .iter()
        .zip(&raw.bones)
        .all(|(a, b)| *a == b.name);
    if !same_order {
        return Err(cur.bad("skeleton bones are not in depth-first order".into()));
    }
    Ok(SkeletonRecord {
        subject_id,
        name,
        skeleton: Arc::new(skeleton),
    })
}

fn decode_frame(
    cur: &mut Cursor<'_>,
    skeletons: &HashMap<u32, Arc<Skeleton>>,
) -> Result<FrameRecord, SourceError> {
    let subject_id = cur.u32("subject id")?;
    let seq = cur.u64("sequence number")?;
    let capture_nanos = cur.u64("capture time")?;
    let flags = cur.u8("flags")?;
    let num_bones = cur.u32("bone count")? as usize;
    let skeleton = skeletons.get(&subject_id).ok_or_else(|| {
        cur.bad(format!(
            "frame for subject {subject_id} before its skeleton"
        ))
    })?;
    if num_bones != skeleton.num_bones() {
        return Err(cur.bad(format!(
            "frame has {num_bones} bones but subject {subject_id}'s skeleton has {}",
            skeleton.num_bones()
        )));
    }
    let mut pose = Pose::from_rest(skeleton);
    let root = cur.f32s::<3>("root translation")?;
    for q in pose.rotations.iter_mut() {
        *q = Quat::from_array(cur.f32s::<4>("rotations")?);
    }
    if flags & FLAG_TRANSLATIONS != 0 {
        for t in pose.translations.iter_mut() {
            *t = Vec3::from_array(cur.f32s::<3>("translations")?);
        }
    }
    pose.translations[0] = Vec3::from_array(root);
    Ok(FrameRecord {
        subject_id,
        seq,
        capture_nanos,
        pose,
    })
}

/// A whole recording in memory.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// Skeleton records in file order.
    pub skeletons: Vec<SkeletonRecord>,
    /// Frame records in file order.
    pub frames: Vec<FrameRecord>,
    /// Raw packets in file order.
    pub raw: Vec<RawPacket>,
    /// True when the end marker was present.
    pub ended_cleanly: bool,
    /// The error that cut the file short, if the tail was truncated (earlier records are kept).
    pub truncated_tail: Option<String>,
    /// Unknown records skipped.
    pub skipped_records: usize,
}

/// Reads a whole recording. A truncated *tail* (what a crash leaves) is tolerated and reported
/// in [`Recording::truncated_tail`]; every other error fails.
pub fn read_recording(input: impl Read) -> Result<Recording, SourceError> {
    let mut reader = RecordingReader::new(input)?;
    let mut rec = Recording::default();
    for r in reader.by_ref() {
        match r {
            Ok(Record::Skeleton(s)) => rec.skeletons.push(s),
            Ok(Record::Frame(f)) => rec.frames.push(f),
            Ok(Record::Raw(p)) => rec.raw.push(p),
            Ok(Record::End) => {}
            Err(e @ SourceError::TruncatedRecord { .. }) => {
                rec.truncated_tail = Some(e.to_string());
            }
            Err(e) => return Err(e),
        }
    }
    rec.ended_cleanly = reader.ended_cleanly();
    rec.skipped_records = reader.skipped_records();
    Ok(rec)
}
