//! Streaming recording writer.

use std::collections::HashMap;
use std::io::{BufWriter, Write};
use std::sync::Arc;

use rigcast_retarget::{Pose, Skeleton};

use super::format::*;
use crate::error::SourceError;

/// Capture time between guaranteed flushes: a crash loses at most about this much.
const FLUSH_INTERVAL_NANOS: u64 = 1_000_000_000;
/// Non-root translations closer than this to rest are not stored.
const REST_TOLERANCE_M: f32 = 1e-7;

/// Writes a recording record by record. Buffered; flushed after every skeleton record and at
/// least once per second of capture time, so a crash loses at most about one second.
/// Call [`RecordingWriter::finish`] to write the end marker.
pub struct RecordingWriter<W: Write> {
    pub(super) out: BufWriter<W>,
    skeletons: HashMap<u32, Arc<Skeleton>>,
    payload: Vec<u8>,
    last_flush_nanos: Option<u64>,
}

impl<W: Write> RecordingWriter<W> {
    /// Writes the file header.
    pub fn new(inner: W) -> Result<Self, SourceError> {
        let mut out = BufWriter::new(inner);
        out.write_all(&MAGIC)?;
        out.write_all(&FORMAT_MAJOR.to_le_bytes())?;
        out.write_all(&FORMAT_MINOR.to_le_bytes())?;
        out.write_all(&0u32.to_le_bytes())?; // reserved flags
        Ok(RecordingWriter {
            out,
            skeletons: HashMap::new(),
            payload: Vec::with_capacity(1024),
            last_flush_nanos: None,
        })
    }

    /// Announces (or replaces) the skeleton of `subject_id`.
    pub fn write_skeleton(
        &mut self,
        subject_id: u32,
        name: &str,
        skeleton: &Arc<Skeleton>,
    ) -> Result<(), SourceError> {
        let p = &mut self.payload;
        p.clear();
        p.extend_from_slice(&subject_id.to_le_bytes());
        put_str(p, name)?;
        p.extend_from_slice(&(skeleton.num_bones() as u32).to_le_bytes());
        for b in skeleton.bone_ids() {
            put_str(p, skeleton.name(b))?;
            let parent = skeleton.parent(b).map(|p| p.0 as u32).unwrap_or(NO_PARENT);
            p.extend_from_slice(&parent.to_le_bytes());
            let r = skeleton.rest()[b.index()];
            put_f32s(p, &r.translation.to_array());
            put_f32s(p, &r.rotation.to_array());
        }
        self.emit(TYPE_SKELETON)?;
        self.skeletons.insert(subject_id, skeleton.clone());
        self.out.flush()?;
        Ok(())
    }

    /// Writes one pose of `subject_id` (its skeleton must have been written). Translations of
    /// bones other than bone 0 are stored only when some differ from rest.
    pub fn write_frame(
        &mut self,
        subject_id: u32,
        seq: u64,
        capture_nanos: u64,
        pose: &Pose,
    ) -> Result<(), SourceError> {
        let skeleton =
            self.skeletons
                .get(&subject_id)
                .ok_or_else(|| SourceError::InvalidOption {
                    reason: format!("frame for subject {subject_id} before its skeleton record"),
                })?;
        pose.check(skeleton)?;
        let rest = skeleton.rest();
        let moved = pose
            .translations
            .iter()
            .zip(rest)
            .skip(1)
            .any(|(t, r)| (*t - r.translation).abs().max_element() > REST_TOLERANCE_M);
        let p = &mut self.payload;
        p.clear();
        p.extend_from_slice(&subject_id.to_le_bytes());
        p.extend_from_slice(&seq.to_le_bytes());
        p.extend_from_slice(&capture_nanos.to_le_bytes());
        p.push(if moved { FLAG_TRANSLATIONS } else { 0 });
        p.extend_from_slice(&(pose.num_bones() as u32).to_le_bytes());
        put_f32s(p, &pose.translations[0].to_array());
        for q in &pose.rotations {
            put_f32s(p, &q.to_array());
        }
        if moved {
            for t in &pose.translations {
                put_f32s(p, &t.to_array());
            }
        }
        self.emit(TYPE_FRAME)?;
        self.maybe_flush(capture_nanos)
    }

    /// Writes raw input bytes (an OSC datagram, serial bytes, …) for later re-parsing.
    pub fn write_raw(
        &mut self,
        source_id: u32,
        kind: RawKind,
        capture_nanos: u64,
        bytes: &[u8],
    ) -> Result<(), SourceError> {
        let p = &mut self.payload;
        p.clear();
        p.extend_from_slice(&source_id.to_le_bytes());
        p.push(kind.code());
        p.extend_from_slice(&capture_nanos.to_le_bytes());
        p.extend_from_slice(bytes);
        self.emit(TYPE_RAW)?;
        self.maybe_flush(capture_nanos)
    }

    /// Flushes buffered records to the underlying writer.
    pub fn flush(&mut self) -> Result<(), SourceError> {
        self.out.flush()?;
        Ok(())
    }

    /// Writes the end marker, flushes, and returns the underlying writer.
    pub fn finish(mut self) -> Result<W, SourceError> {
        self.payload.clear();
        self.emit(TYPE_END)?;
        self.out.flush()?;
        self.out
            .into_inner()
            .map_err(|e| SourceError::Stream(e.into_error()))
    }

    fn emit(&mut self, kind: u8) -> Result<(), SourceError> {
        if self.payload.len() > MAX_RECORD_BYTES as usize {
            return Err(SourceError::InvalidOption {
                reason: format!(
                    "record of {} bytes exceeds the format limit of {MAX_RECORD_BYTES}",
                    self.payload.len()
                ),
            });
        }
        self.out.write_all(&[kind])?;
        self.out
            .write_all(&(self.payload.len() as u32).to_le_bytes())?;
        self.out.write_all(&self.payload)?;
        Ok(())
    }

    fn maybe_flush(&mut self, capture_nanos: u64) -> Result<(), SourceError> {
        let due = match self.last_flush_nanos {
            None => true,
            // A clock that jumps backwards also triggers a flush (and restarts the interval).
            Some(last) => capture_nanos < last || capture_nanos - last >= FLUSH_INTERVAL_NANOS,
        };
        if due {
            self.out.flush()?;
            self.last_flush_nanos = Some(capture_nanos);
        }
        Ok(())
    }
}

fn put_str(p: &mut Vec<u8>, s: &str) -> Result<(), SourceError> {
    let len = u16::try_from(s.len()).map_err(|_| SourceError::InvalidOption {
        reason: format!("name of {} bytes is longer than 65535", s.len()),
    })?;
    p.extend_from_slice(&len.to_le_bytes());
    p.extend_from_slice(s.as_bytes());
    Ok(())
}

fn put_f32s(p: &mut Vec<u8>, values: &[f32]) {
    for v in values {
        p.extend_from_slice(&v.to_le_bytes());
    }
}
