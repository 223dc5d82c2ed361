//! Another node's subject on this node: [`run_relay`] forwards its frames to this node's
//! clients the moment they arrive (only the subject id is rewritten to this node's), and hands
//! them to a [`RemoteSource`], which makes it an ordinary live source for performers, VMC out
//! and `source_status`. What the bucket says about the subject later (a new skeleton, the
//! entry removed or aged out) reaches the source as a [`Change`]. A subject a performer
//! names before its node published it starts [`RemoteSource::awaiting`] its entry.

use std::sync::atomic::Ordering;
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use futures_util::StreamExt;
use glam::{Quat, Vec3};
use rigcast_protocol::frame::{decode_any_into, decode_header_any, frame_len, FrameHeader};
use rigcast_protocol::SourceState;
use rigcast_retarget::{Pose, Skeleton};
use rigcast_sources::live::{FrameMeta, HealthTracker, LiveSource, NextFrame, SourceStatus};
use tokio_tungstenite::tungstenite::Bytes;

use rigcast_protocol::control::BoneInfo;

use super::SubjectEntry;
use crate::state::Feeds;
use rigcast_engine::clock::unix_nanos;
use rigcast_engine::tick::OutFrame;

/// Frames waiting for the source thread; it only ever needs the newest, so a full queue
/// drops (the relay to clients is not affected).
const QUEUE: usize = 8;
/// Offset of the subject id in a frame header (both versions).
const SUBJECT_AT: usize = 8;

/// Changes of queued at most (entries change rarely; a full queue drops the newest, and the
/// next change of the same entry brings it up to date).
const CHANGES: usize = 4;

/// What the bucket says about a relayed subject after it was made.
#[derive(Debug, Clone)]
pub enum Change {
    /// Its entry was put again (its node restarted, or its skeleton changed).
    Entry(Box<SubjectEntry>),
    /// Its entry was deleted (its node stopped) or purged.
    Removed,
    /// Its entry was not put again for [`super::ENTRY_MAX_AGE`]: its node stopped answering
    /// (killed, or cut off from NATS).
    Expired,
}

/// Why an expired subject is lost.
const EXPIRED: &str = "its node stopped answering";

/// The queues that feed a [`RemoteSource`].
pub struct RemoteFeeds {
    /// The subject's frames, from its relay.
    pub frames: SyncSender<Bytes>,
    /// Its entry's changes, from the bucket watch.
    pub changes: SyncSender<Change>,
}

/// A live source fed by the frames another node publishes for one of its subjects.
pub struct RemoteSource {
    name: String,
    bones: Vec<BoneInfo>,
    skeleton: Arc<Skeleton>,
    /// Bones whose translation version 2 frames carry, in bone order.
    translated: Vec<usize>,
    rx: Receiver<Bytes>,
    changes: Receiver<Change>,
    /// Its node.
    site: String,
    /// The bucket has no entry of it (removed, or not published yet): frames still arriving
    /// are not taken as the subject being live.
    absent: bool,
    health: HealthTracker,
    rotations: Vec<Quat>,
    translations: Vec<Vec3>,
    announced: bool,
}

impl RemoteSource {
    /// The source of `entry`'s subject, and the queues that feed it.
    pub fn new(
        entry: &SubjectEntry,
        lost_after: Duration,
    ) -> anyhow::Result<(RemoteSource, RemoteFeeds)> {
        let skeleton = Arc::new(crate::skeleton_wire::skeleton_from_bones(&entry.bones)?);
        let mut made =
            Self::with_skeleton(&entry.site, &entry.relayed_name(), skeleton, lost_after);
        made.0.translated = translated_of(&entry.bones);
        made.0.bones = entry.bones.clone();
        made.0.absent = false;
        Ok(made)
    }

    /// The source of subject `name` of `site`, which its node has not published yet: it waits
    /// (`connecting`) for the entry, with the standard humanoid standing in for its skeleton
    /// (as for a VMC sender not heard yet), and takes frames once the entry is there.
    pub fn awaiting(
        site: &str,
        name: &str,
        lost_after: Duration,
    ) -> anyhow::Result<(RemoteSource, RemoteFeeds)> {
        let skeleton = rigcast_sources::live::humanoid::default_humanoid()
            .context("building the default humanoid")?;
        let relayed = format!("{name}@{site}");
        let mut made = Self::with_skeleton(site, &relayed, skeleton, lost_after);
        made.0
            .health
            .set_detail(&format!("waiting for node {site} to publish {name}"));
        Ok(made)
    }

    fn with_skeleton(
        site: &str,
        name: &str,
        skeleton: Arc<Skeleton>,
        lost_after: Duration,
    ) -> (RemoteSource, RemoteFeeds) {
        let (tx, rx) = sync_channel(QUEUE);
        let (changes_tx, changes) = sync_channel(CHANGES);
        let mut health = HealthTracker::new(lost_after);
        health.set_detail(&format!("relayed from {site}"));
        let source = RemoteSource {
            name: name.to_string(),
            // Empty: no entry yet, so the first one differs and brings its skeleton.
            bones: Vec::new(),
            skeleton,
            translated: Vec::new(),
            rx,
            changes,
            site: site.to_string(),
            absent: true,
            health,
            rotations: Vec::new(),
            translations: Vec::new(),
            announced: false,
        };
        let feeds = RemoteFeeds {
            frames: tx,
            changes: changes_tx,
        };
        (source, feeds)
    }

    /// Applies the bucket's news: a new skeleton is announced with the next frame on it; a
    /// removed entry makes the subject lost until it is put again; an expired one too, unless
    /// its frames still arrive (then its node answers, only its bucket writes do not).
    fn apply_changes(&mut self) {
        while let Ok(change) = self.changes.try_recv() {
            match change {
                Change::Entry(entry) => self.on_entry(*entry),
                Change::Removed => {
                    self.absent = true;
                    self.health
                        .on_device_lost("its node removed it from the cluster");
                }
                Change::Expired if self.health.state() == SourceState::Live => {}
                Change::Expired => self.health.on_gone(EXPIRED),
            }
        }
    }

    /// The entry was put (first, again after a removal, or with a new skeleton).
    fn on_entry(&mut self, entry: SubjectEntry) {
        if std::mem::take(&mut self.absent) && self.health.state() == SourceState::Connecting {
            // It was waiting for its node to publish it.
            self.health
                .set_detail(&format!("relayed from {}", self.site));
        }
        if entry.bones == self.bones {
            return;
        }
        match crate::skeleton_wire::skeleton_from_bones(&entry.bones) {
            Ok(skeleton) => {
                self.skeleton = Arc::new(skeleton);
                self.translated = translated_of(&entry.bones);
                self.bones = entry.bones;
                self.announced = false;
            }
            Err(e) => self.health.on_device_lost(format!("bad skeleton: {e}")),
        }
    }

    /// Its skeleton.
    pub fn skeleton_arc(&self) -> Arc<Skeleton> {
        self.skeleton.clone()
    }

    /// Fills `out` from a published message (version 1 then version 2 frame); the header, or
    /// `None` when it does not fit this subject's skeleton.
    fn decode(&mut self, bytes: &[u8], out: &mut Pose) -> Option<FrameHeader> {
        let v2 = bytes.get(v1_len(bytes)?..)?;
        let (header, _) = decode_any_into(v2, &mut self.rotations, &mut self.translations).ok()?;
        let n = self.skeleton.num_bones();
        if self.rotations.len() != n || self.translations.len() != self.translated.len() {
            return None;
        }
        if out.num_bones() != n {
            *out = self.skeleton.rest_pose(); // only after a skeleton change
        }
        out.rotations.copy_from_slice(&self.rotations);
        for (i, t) in out.translations.iter_mut().enumerate() {
            *t = self.skeleton.rest()[i].translation;
        }
        for (&bone, &t) in self.translated.iter().zip(&self.translations) {
            out.translations[bone] = t;
        }
        Some(header)
    }
}

impl LiveSource for RemoteSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn skeleton(&self) -> Option<Arc<Skeleton>> {
        Some(self.skeleton.clone())
    }

    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame {
        self.apply_changes();
        match self.rx.recv_timeout(timeout) {
            Ok(_) if self.absent => {}
            Ok(bytes) => {
                let now = Instant::now();
                if let Some(h) = self.decode(&bytes, out) {
                    self.health.on_input(now);
                    // Publish (the other node's encode) to here: the hop through NATS.
                    let hop = unix_nanos().saturating_sub(h.send_nanos);
                    self.health.on_frame(now, Duration::from_nanos(hop));
                    let skeleton_changed = !self.announced;
                    self.announced = true;
                    return Ok(Some(FrameMeta {
                        seq: h.seq,
                        capture_nanos: h.capture_nanos,
                        skeleton_changed,
                    }));
                }
                self.health.on_dropped(1);
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                // The relay ended (shutdown, or NATS refused the subscription).
                self.health.on_device_lost("relay stopped");
                std::thread::sleep(timeout);
            }
        }
        self.health.poll(Instant::now());
        Ok(None)
    }

    fn status(&self) -> SourceStatus {
        self.health.status()
    }
}

/// Indices of the bones whose translation version 2 frames carry.
fn translated_of(bones: &[BoneInfo]) -> Vec<usize> {
    (bones.iter().enumerate())
        .filter(|(_, b)| b.translated)
        .map(|(i, _)| i)
        .collect()
}

/// Length of the version 1 frame at the start of a published message.
fn v1_len(bytes: &[u8]) -> Option<usize> {
    let n = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?);
    Some(frame_len(n as usize))
}

/// A published message as this node's frame of subject `id`: validated, with the subject id
/// of both versions rewritten; `None` when malformed.
pub fn relabel(bytes: &[u8], id: u32) -> Option<OutFrame> {
    let v2_at = v1_len(bytes)?;
    decode_header_any(bytes.get(..v2_at)?).ok()?;
    let has_v2 = bytes.len() > v2_at;
    if has_v2 {
        decode_header_any(&bytes[v2_at..]).ok()?;
    }
    let mut own = bytes.to_vec();
    own[SUBJECT_AT..SUBJECT_AT + 4].copy_from_slice(&id.to_le_bytes());
    if has_v2 {
        own[v2_at + SUBJECT_AT..v2_at + SUBJECT_AT + 4].copy_from_slice(&id.to_le_bytes());
    }
    Some(OutFrame {
        subject: id,
        bytes: Bytes::from(own),
        v2_at,
        // Timed by the node that encoded it, on its own clock.
        capture_nanos: 0,
        send_nanos: 0,
    })
}

/// Subscribes to `subject` (another node's frames) and forwards every message to this node's
/// clients as subject `id`, and to its source, until shutdown.
pub async fn run_relay(
    client: async_nats::Client,
    subject: String,
    id: u32,
    to_source: SyncSender<Bytes>,
    feeds: Feeds,
) {
    let mut sub = match client.subscribe(subject.clone()).await {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cluster: cannot subscribe to {subject}: {e}");
            return;
        }
    };
    let mut shutdown = feeds.shutdown.clone();
    loop {
        tokio::select! {
            biased;
            _ = shutdown.changed() => break,
            msg = sub.next() => {
                let Some(msg) = msg else { break };
                let Some(frame) = relabel(&msg.payload, id) else {
                    feeds.stats.cluster_bad_frames.fetch_add(1, Ordering::Relaxed);
                    continue;
                };
                // Err only means "no client connected right now".
                let _ = feeds.frames.send(frame);
                match to_source.try_send(msg.payload) {
                    Ok(()) | Err(TrySendError::Full(_)) => {}
                    Err(TrySendError::Disconnected(_)) => break,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_protocol::frame::{append_frame_v2, decode_frame, encode_frame};

    fn published(subject: u32) -> Vec<u8> {
        let header = FrameHeader {
            flags: 0,
            subject,
            seq: 42,
            capture_nanos: 1,
            send_nanos: 2,
            missed_frames: 0,
        };
        let rotations = [Quat::IDENTITY, Quat::from_rotation_y(0.5)];
        let mut out = Vec::new();
        encode_frame(&mut out, &header, Vec3::new(0.0, 1.0, 0.0), &rotations);
        append_frame_v2(&mut out, &header, &rotations, &[Vec3::Y, Vec3::X], &[0]);
        out
    }

    #[test]
    fn relabelling_changes_only_the_subject_id() {
        let bytes = published(7);
        let f = relabel(&bytes, 3).unwrap();
        assert_eq!(f.subject, 3);
        let (v1, v2) = (f.version(1), f.version(2));
        let d = decode_frame(&v1).unwrap();
        assert_eq!(
            (d.header.subject, d.header.seq, d.header.send_nanos),
            (3, 42, 2)
        );
        assert_eq!(decode_header_any(&v2).unwrap().0.subject, 3);
        let mut back = f.bytes.to_vec();
        back[SUBJECT_AT..SUBJECT_AT + 4].copy_from_slice(&7u32.to_le_bytes());
        let at = f.v2_at + SUBJECT_AT;
        back[at..at + 4].copy_from_slice(&7u32.to_le_bytes());
        assert_eq!(back, bytes);
    }

    fn chain(n: usize) -> SubjectEntry {
        let bones = (0..n)
            .map(|i| BoneInfo {
                name: format!("b{i}"),
                parent: i.checked_sub(1).map(|p| p as u32),
                rest_translation: [0.0, 0.1, 0.0],
                rest_rotation: [0.0, 0.0, 0.0, 1.0],
                translated: i == 0,
            })
            .collect();
        SubjectEntry {
            site: "a".into(),
            name: "walk".into(),
            bones,
            mapping: None,
        }
    }

    /// A published message of `n` bones (bone 0 translated), seq `seq`.
    /// The node puts an entry of `n` bones, then publishes frame `seq` on it.
    fn put_and_publish(feeds: &RemoteFeeds, n: usize, seq: u64) {
        feeds
            .changes
            .send(Change::Entry(Box::new(chain(n))))
            .unwrap();
        feeds.frames.send(published_n(n, seq)).unwrap();
    }

    fn published_n(n: usize, seq: u64) -> Bytes {
        let header = FrameHeader {
            flags: 0,
            subject: 0,
            seq,
            capture_nanos: 1,
            send_nanos: unix_nanos(),
            missed_frames: 0,
        };
        let rotations = vec![Quat::from_rotation_y(0.25); n];
        let translations = vec![Vec3::Y; n];
        let mut out = Vec::new();
        encode_frame(&mut out, &header, Vec3::Y, &rotations);
        append_frame_v2(&mut out, &header, &rotations, &translations, &[0]);
        Bytes::from(out)
    }

    #[test]
    fn bucket_changes_reach_the_source() {
        let (mut source, feeds) = RemoteSource::new(&chain(2), Duration::from_secs(5)).unwrap();
        let mut pose = source.skeleton_arc().rest_pose();
        let wait = Duration::from_millis(100);
        feeds.frames.send(published_n(2, 1)).unwrap();
        let first = source.next_frame(wait, &mut pose).unwrap().unwrap();
        assert!(
            first.skeleton_changed,
            "the first frame announces the skeleton"
        );
        feeds.frames.send(published_n(2, 2)).unwrap();
        assert!(
            !source
                .next_frame(wait, &mut pose)
                .unwrap()
                .unwrap()
                .skeleton_changed
        );
        // The node's skeleton grew: frames on it are taken, announced as a new skeleton.
        put_and_publish(&feeds, 3, 3);
        let grown = source.next_frame(wait, &mut pose).unwrap().unwrap();
        assert!(grown.skeleton_changed);
        assert_eq!(source.skeleton().unwrap().num_bones(), 3);
        assert_eq!(pose.num_bones(), 3);
        // Removed: lost, and frames no longer count.
        feeds.changes.send(Change::Removed).unwrap();
        feeds.frames.send(published_n(3, 4)).unwrap();
        assert!(source.next_frame(wait, &mut pose).unwrap().is_none());
        let status = source.status();
        assert_eq!(status.state, rigcast_protocol::SourceState::Lost);
        assert!(status.detail.contains("removed"), "{}", status.detail);
        // Put again: live with the next frame.
        put_and_publish(&feeds, 3, 5);
        assert_eq!(source.next_frame(wait, &mut pose).unwrap().unwrap().seq, 5);
        assert_eq!(source.status().state, rigcast_protocol::SourceState::Live);
    }

    #[test]
    fn an_awaited_subject_waits_for_its_entry_and_an_expired_one_is_lost() {
        let (mut source, feeds) =
            RemoteSource::awaiting("a", "walk", Duration::from_secs(5)).unwrap();
        let mut pose = source.skeleton_arc().rest_pose();
        let wait = Duration::from_millis(100);
        // Frames before the entry do not count: it waits, and says for what.
        feeds.frames.send(published_n(2, 1)).unwrap();
        assert!(source.next_frame(wait, &mut pose).unwrap().is_none());
        let status = source.status();
        assert_eq!(status.state, SourceState::Connecting);
        assert_eq!(status.detail, "waiting for node a to publish walk");
        // The entry arrives: its skeleton replaces the stand-in, announced with the frame.
        put_and_publish(&feeds, 2, 2);
        let first = source.next_frame(wait, &mut pose).unwrap().unwrap();
        assert!(first.skeleton_changed);
        assert_eq!(source.skeleton().unwrap().num_bones(), 2);
        assert_eq!(source.status().state, SourceState::Live);
        // Expired while its frames still arrive: its node answers, so it stays live.
        feeds.changes.send(Change::Expired).unwrap();
        feeds.frames.send(published_n(2, 3)).unwrap();
        assert!(source.next_frame(wait, &mut pose).unwrap().is_some());
        assert_eq!(source.status().state, SourceState::Live);

        // A subject made from an entry whose node is gone (no frame ever): lost, saying why.
        let (mut stale, feeds) = RemoteSource::new(&chain(2), Duration::from_secs(5)).unwrap();
        feeds.changes.send(Change::Expired).unwrap();
        assert!(stale.next_frame(wait, &mut pose).unwrap().is_none());
        let status = stale.status();
        assert_eq!(status.state, SourceState::Lost);
        assert_eq!(status.detail, EXPIRED);
        // Its node back: the same entry again, then its frames make it live.
        put_and_publish(&feeds, 2, 1);
        assert!(stale.next_frame(wait, &mut pose).unwrap().is_some());
        assert_eq!(stale.status().state, SourceState::Live);
    }

    #[test]
    fn malformed_messages_are_refused() {
        let bytes = published(7);
        assert!(relabel(&bytes[..20], 1).is_none());
        assert!(relabel(&bytes[..bytes.len() - 3], 1).is_none());
        assert!(relabel(b"not a frame at all", 1).is_none());
        assert!(relabel(&[], 1).is_none());
    }
}
