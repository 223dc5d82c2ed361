//! Converting between recordings and clips.

use std::io::Write;

use rigcast_retarget::Clip;

use super::reader::Recording;
use super::writer::RecordingWriter;
use crate::error::SourceError;

/// Frame interval used when a recording has fewer than two frames of its subject.
const FALLBACK_FRAME_TIME_SECS: f64 = 1.0 / 60.0;

/// The first subject's frames as a clip, played at the median interval between their capture
/// times (robust to a few dropped or late frames).
pub fn clip_from_recording(rec: &Recording, name: &str) -> Result<Clip, SourceError> {
    let first = rec.skeletons.first().ok_or_else(|| SourceError::NoFrames {
        reason: "the recording has no skeleton record".into(),
    })?;
    let subject = first.subject_id;
    let frames: Vec<_> = rec
        .frames
        .iter()
        .filter(|f| f.subject_id == subject)
        .collect();
    let mut deltas: Vec<u64> = frames
        .windows(2)
        .filter_map(|w| w[1].capture_nanos.checked_sub(w[0].capture_nanos))
        .filter(|&d| d > 0)
        .collect();
    deltas.sort_unstable();
    let frame_time_secs = match deltas.get(deltas.len() / 2) {
        Some(&d) => d as f64 * 1e-9,
        None => FALLBACK_FRAME_TIME_SECS,
    };
    // A later skeleton record for the same subject would change the bone layout mid-clip; keep
    // only frames that fit the first skeleton.
    let poses = frames
        .iter()
        .filter(|f| f.pose.check(&first.skeleton).is_ok())
        .map(|f| f.pose.clone())
        .collect();
    let clip_name = if first.name.is_empty() {
        name
    } else {
        &first.name
    };
    Ok(Clip::new(
        clip_name,
        first.skeleton.clone(),
        poses,
        frame_time_secs,
    )?)
}

/// Writes `clip` as a recording with one subject (id 0), frames at `k × frame_time`.
pub fn write_clip_recording<W: Write>(out: W, clip: &Clip) -> Result<W, SourceError> {
    let mut w = RecordingWriter::new(out)?;
    w.write_skeleton(0, &clip.name, &clip.skeleton)?;
    for (k, pose) in clip.poses.iter().enumerate() {
        let nanos = (k as f64 * clip.frame_time_secs * 1e9).round() as u64;
        w.write_frame(0, k as u64, nanos, pose)?;
    }
    w.finish()
}
