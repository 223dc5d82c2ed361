//! A stream saved as a recording (`rigcast record`): connect to a server as an ordinary
//! client and save what it streams: each subject's skeleton record
//! (from its `skeleton` message), then one frame record per binary frame.
//!
//! Binary frames carry rotations and the root translation only, so recorded non-root
//! translations are the rest offsets.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{bail, Context};
use futures_util::StreamExt;
use glam::Quat;
use rigcast_protocol::frame::decode_frame_into;
use rigcast_protocol::ServerMessage;
use rigcast_retarget::{Pose, Skeleton};
use rigcast_sources::recording::RecordingWriter;
use tokio_tungstenite::tungstenite::Message;

use crate::skeleton_wire::skeleton_from_bones;

/// What a recording session wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RecordSummary {
    /// Skeleton records.
    pub skeletons: usize,
    /// Frame records.
    pub frames: usize,
}

struct SubjectTrack {
    skeleton: Arc<Skeleton>,
    pose: Pose,
}

/// Connects to `url` and writes the stream to `output` until `stop` completes or the server
/// closes the connection.
pub async fn record(
    url: &str,
    output: &Path,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<RecordSummary> {
    let (mut ws, _) = tokio_tungstenite::connect_async(url)
        .await
        .with_context(|| format!("cannot connect to {url}"))?;
    let file = std::fs::File::create(output)
        .with_context(|| format!("cannot create {}", output.display()))?;
    let mut rec = Recorder {
        writer: RecordingWriter::new(file)?,
        tracks: HashMap::new(),
        rotations: Vec::new(),
        summary: RecordSummary::default(),
    };
    tokio::pin!(stop);
    loop {
        let msg = tokio::select! {
            _ = &mut stop => break,
            msg = ws.next() => msg,
        };
        let Some(msg) = msg else { break };
        match msg.context("stream error")? {
            Message::Text(text) => rec.on_text(text.as_str())?,
            Message::Binary(bytes) => rec.on_frame(&bytes)?,
            Message::Close(_) => break,
            _ => {}
        }
    }
    let Recorder {
        writer, summary, ..
    } = rec;
    writer.finish()?;
    // The file is finished; a server already gone needs no close frame.
    let _ = ws.close(None).await;
    Ok(summary)
}

/// What `record` keeps while the stream lasts: the file, each subject's skeleton and last
/// pose, a frame's decoding buffer, and the counts.
struct Recorder<W: std::io::Write> {
    writer: RecordingWriter<W>,
    tracks: HashMap<u32, SubjectTrack>,
    rotations: Vec<Quat>,
    summary: RecordSummary,
}

impl<W: std::io::Write> Recorder<W> {
    /// A JSON message: a subject's skeleton starts (or restarts) its track; others are not
    /// recorded.
    fn on_text(&mut self, text: &str) -> anyhow::Result<()> {
        let parsed: ServerMessage = serde_json::from_str(text)
            .with_context(|| format!("server sent undecodable JSON: {text}"))?;
        let ServerMessage::Skeleton {
            subject,
            name,
            fingerprint,
            bones,
        } = parsed
        else {
            return Ok(());
        };
        let skeleton = Arc::new(
            skeleton_from_bones(&bones)
                .with_context(|| format!("skeleton of subject {subject} ({name}) is invalid"))?,
        );
        if skeleton.fingerprint_hex() != fingerprint {
            // f32 → JSON → f32 is exact for serde_json, so a mismatch means a bug somewhere;
            // warn, but keep the data.
            eprintln!(
                "rigcast record: subject {subject}: fingerprint {} differs from the server's {fingerprint}",
                skeleton.fingerprint_hex()
            );
        }
        self.writer.write_skeleton(subject, &name, &skeleton)?;
        self.summary.skeletons += 1;
        let pose = Pose::from_rest(&skeleton);
        self.tracks.insert(subject, SubjectTrack { pose, skeleton });
        Ok(())
    }

    /// A binary frame: written as its subject's pose, once its skeleton is known.
    fn on_frame(&mut self, bytes: &[u8]) -> anyhow::Result<()> {
        let (header, root) = decode_frame_into(bytes, &mut self.rotations)
            .context("server sent an invalid frame")?;
        let Some(track) = self.tracks.get_mut(&header.subject) else {
            return Ok(()); // frame before its skeleton: nothing to attach it to
        };
        if self.rotations.len() != track.skeleton.num_bones() {
            bail!(
                "frame of subject {} has {} bones, its skeleton {}",
                header.subject,
                self.rotations.len(),
                track.skeleton.num_bones()
            );
        }
        track.pose.rotations.copy_from_slice(&self.rotations);
        track.pose.set_root_translation(root);
        let (subject, seq, capture) = (header.subject, header.seq, header.capture_nanos);
        self.writer
            .write_frame(subject, seq, capture, &track.pose)?;
        self.summary.frames += 1;
        Ok(())
    }
}
