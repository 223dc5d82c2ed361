#![allow(clippy::unwrap_used)]

use std::io::Write;
use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_retarget::{Pose, RawSkeleton, Skeleton, Transform};

use super::format::{TYPE_FRAME, TYPE_SKELETON};
use super::*;
use crate::error::SourceError;

fn skeleton() -> Arc<Skeleton> {
    let mut raw = RawSkeleton::default();
    let r = raw.add(
        "root",
        None,
        Transform::from_translation(Vec3::new(0.0, 1.0, 0.0)),
    );
    let a = raw.add("spine", Some(r), Transform::from_translation(Vec3::Y * 0.3));
    raw.add(
        "head",
        Some(a),
        Transform {
            translation: Vec3::Y * 0.2,
            rotation: Quat::from_rotation_x(0.1),
        },
    );
    Arc::new(Skeleton::build(&raw).unwrap())
}

fn pose(k: u64, s: &Skeleton) -> Pose {
    let mut p = s.rest_pose();
    p.translations[0] = Vec3::new(k as f32 * 0.1, 1.0, 0.0);
    p.rotations[1] = Quat::from_rotation_z(k as f32 * 0.01);
    if k == 2 {
        // A non-root translation that differs from rest must be stored.
        p.translations[2] = Vec3::new(0.0, 0.25, 0.01);
    }
    p
}

/// skeleton, frames 0..4 at 50 Hz, one raw packet, end.
fn sample_file() -> Vec<u8> {
    let s = skeleton();
    let mut w = RecordingWriter::new(Vec::new()).unwrap();
    w.write_skeleton(7, "alice", &s).unwrap();
    for k in 0..4u64 {
        w.write_frame(7, k, 1_000 + k * 20_000_000, &pose(k, &s))
            .unwrap();
    }
    w.write_raw(3, RawKind::Osc, 5, b"/VMC/Ext/OK\0").unwrap();
    w.finish().unwrap()
}

#[test]
fn round_trip_keeps_everything() {
    let bytes = sample_file();
    let rec = read_recording(&bytes[..]).unwrap();
    assert!(rec.ended_cleanly && rec.truncated_tail.is_none());
    assert_eq!(rec.skeletons.len(), 1);
    assert_eq!(rec.skeletons[0].name, "alice");
    assert_eq!(*rec.skeletons[0].skeleton, *skeleton());
    assert_eq!(rec.frames.len(), 4);
    let s = skeleton();
    for (k, f) in rec.frames.iter().enumerate() {
        assert_eq!(f.seq, k as u64);
        assert_eq!(f.subject_id, 7);
        assert_eq!(f.pose, pose(k as u64, &s), "frame {k}");
    }
    assert_eq!(rec.raw[0].bytes, b"/VMC/Ext/OK\0");
    assert_eq!(rec.raw[0].kind, RawKind::Osc);
    // Only the frame with a moved non-root bone carries all translations: 3×(4 + 8 + 8 + 1 +
    // 4 + 12 + 48) + (… + 36) bytes of payload.
    let clip = clip_from_recording(&rec, "x").unwrap();
    assert_eq!(clip.num_frames(), 4);
    assert!((clip.frame_time_secs - 0.02).abs() < 1e-12);
}

#[test]
fn frames_without_moved_bones_skip_translations() {
    let s = skeleton();
    let size = |p: &Pose| {
        let mut w = RecordingWriter::new(Vec::new()).unwrap();
        w.write_skeleton(0, "", &s).unwrap();
        let before = w.out.get_ref().len() + w.out.buffer().len();
        w.write_frame(0, 0, 0, p).unwrap();
        w.out.get_ref().len() + w.out.buffer().len() - before
    };
    assert_eq!(size(&pose(1, &s)), 5 + 4 + 8 + 8 + 1 + 4 + 12 + 3 * 16);
    assert_eq!(
        size(&pose(2, &s)),
        5 + 4 + 8 + 8 + 1 + 4 + 12 + 3 * 16 + 3 * 12
    );
}

#[test]
fn truncation_anywhere_keeps_earlier_records_and_never_panics() {
    let bytes = sample_file();
    let full = read_recording(&bytes[..]).unwrap();
    for cut in 16..bytes.len() {
        let rec = read_recording(&bytes[..cut]).unwrap();
        assert!(!rec.ended_cleanly);
        // Every record that was fully present is returned, in order.
        assert!(rec.frames.len() <= full.frames.len());
        for (a, b) in rec.frames.iter().zip(&full.frames) {
            assert_eq!(a, b);
        }
    }
    // Cutting in the middle of the last frame reports a truncated tail with its offset.
    let rec = read_recording(&bytes[..bytes.len() - 30]).unwrap();
    assert!(rec.truncated_tail.unwrap().contains("truncated record"));
    // The raw iterator reports it as an error item, after the good records.
    let items: Vec<_> = RecordingReader::new(&bytes[..bytes.len() - 30])
        .unwrap()
        .collect();
    assert!(matches!(
        items.last(),
        Some(Err(SourceError::TruncatedRecord { .. }))
    ));
    assert!(items[..items.len() - 1].iter().all(|r| r.is_ok()));
    for cut in 0..16 {
        assert!(RecordingReader::new(&bytes[..cut]).is_err());
    }
}

#[test]
fn bad_magic_and_newer_version_are_rejected() {
    let mut bytes = sample_file();
    let e = RecordingReader::new(&b"HIERARCHY\nROOT x"[..])
        .err()
        .unwrap();
    assert!(matches!(e, SourceError::BadMagic { .. }), "{e}");
    bytes[8] = 2; // major version 2
    let e = RecordingReader::new(&bytes[..]).err().unwrap();
    assert!(
        matches!(
            e,
            SourceError::UnsupportedVersion {
                found: 2,
                supported: 1
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("version 2"));
    // A newer minor version is fine.
    bytes[8] = 1;
    bytes[10] = 9;
    assert_eq!(RecordingReader::new(&bytes[..]).unwrap().version(), (1, 9));
}

#[test]
fn absurd_length_prefix_is_an_error_without_allocating() {
    let mut bytes = sample_file()[..16].to_vec();
    bytes.push(TYPE_FRAME);
    bytes.extend_from_slice(&u32::MAX.to_le_bytes());
    let e = read_recording(&bytes[..]).err().unwrap();
    assert!(
        matches!(e, SourceError::RecordTooLarge { offset: 16, .. }),
        "{e}"
    );
    // Under the limit but far past the end of the file: truncated, and the buffer only grew to
    // the bytes actually present.
    let mut bytes = sample_file()[..16].to_vec();
    bytes.push(TYPE_SKELETON);
    bytes.extend_from_slice(&(60u32 << 20).to_le_bytes());
    bytes.extend_from_slice(&[0u8; 10]);
    let mut r = RecordingReader::new(&bytes[..]).unwrap();
    assert!(matches!(
        r.next(),
        Some(Err(SourceError::TruncatedRecord { found: 15, .. }))
    ));
    assert!(r.payload.capacity() < 1 << 20);
    assert!(r.next().is_none());
}

#[test]
fn unknown_record_types_are_skipped() {
    let bytes = sample_file();
    let mut patched = bytes[..16].to_vec();
    patched.push(0x42);
    patched.extend_from_slice(&3u32.to_le_bytes());
    patched.extend_from_slice(b"abc");
    patched.extend_from_slice(&bytes[16..]);
    let rec = read_recording(&patched[..]).unwrap();
    assert_eq!(rec.skipped_records, 1);
    assert_eq!(rec.frames.len(), 4);
}

#[test]
fn inconsistent_records_are_errors() {
    let s = skeleton();
    // A frame whose bone count does not match its skeleton.
    let mut w = RecordingWriter::new(Vec::new()).unwrap();
    w.write_skeleton(0, "", &s).unwrap();
    w.write_frame(0, 0, 0, &s.rest_pose()).unwrap();
    let mut bytes = w.finish().unwrap();
    let frame_at = bytes.len() - 5 - (5 + 4 + 8 + 8 + 1 + 4 + 12 + 48);
    assert_eq!(bytes[frame_at], TYPE_FRAME);
    bytes[frame_at + 5 + 21] = 9; // bone count 3 → 9
    let e = read_recording(&bytes[..]).err().unwrap();
    assert!(matches!(e, SourceError::BadRecord { .. }), "{e}");
    // A frame before any skeleton.
    let mut w = RecordingWriter::new(Vec::new()).unwrap();
    assert!(w.write_frame(1, 0, 0, &s.rest_pose()).is_err());
}

/// Counts flushes reaching the inner writer.
#[derive(Default)]
struct FlushCounter {
    data: Vec<u8>,
    flushes: usize,
}

impl Write for FlushCounter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.data.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.flushes += 1;
        Ok(())
    }
}

#[test]
fn flushes_once_per_second_of_capture_time() {
    let s = skeleton();
    let mut w = RecordingWriter::new(FlushCounter::default()).unwrap();
    w.write_skeleton(0, "", &s).unwrap();
    // 10 s at 100 Hz: first frame, then every second → 1 (skeleton) + 1 + 9 flushes.
    for k in 0..1000u64 {
        w.write_frame(0, k, k * 10_000_000, &s.rest_pose()).unwrap();
    }
    let flushes = w.out.get_ref().flushes;
    assert_eq!(flushes, 11);
    // Everything written before the last flush is readable even without finish().
    let data = w.out.get_ref().data.clone();
    let rec = read_recording(&data[..]).unwrap();
    assert!(rec.frames.len() >= 900, "{}", rec.frames.len());
}
