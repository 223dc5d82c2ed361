//! Discovery: this node watches the subject bucket for as long as it runs, so another node
//! that starts later, a subject that appears, or one whose skeleton changes is picked up
//! without a restart here.
//!
//! ```text
//!  KV watch "{ns}_subjects" (last value per key, then every change)
//!    put, new key        ─▶ a new relayed subject: relay task + RemoteSource thread, clients
//!                           told (`subjects_changed`, `skeleton`)
//!    put, known key      ─▶ Change::Entry ─▶ its RemoteSource (first entry of a subject a
//!                           performer waits for, new skeleton, or back after a removal)
//!    put, same entry     ─▶ nothing (a heartbeat): only its node's deadline moves on
//!    delete / purge      ─▶ Change::Removed ─▶ the subject is lost ("removed from the cluster")
//!    no put for ENTRY_MAX_AGE ─▶ Change::Expired ─▶ lost ("its node stopped answering")
//! ```
//!
//! NATS drops an aged-out entry without telling watchers (no marker before server 2.11), so
//! the age is tracked here: each known entry has a deadline, moved on by every new revision.
//! Subjects are never taken away here (clients keep their ids); a removed one stays, lost,
//! until its node puts it again. A performer of this node keeps the sources it was started
//! with, and those include the `NAME@SITE` subjects it names that were not published yet
//! (made at start, waiting): their first entry arrives here like any other change.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::TrySendError;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_nats::jetstream::kv::Operation;
use futures_util::StreamExt;
use rigcast_protocol::SourceKind;

use super::{
    run_relay, Change, Cluster, Forwarder, Origin, RemoteSource, SubjectEntry, ENTRY_MAX_AGE,
};
use crate::live::{LiveContext, LiveFeed};
use crate::state::{Discovery, Feeds};
use rigcast_engine::settings::VmcBoneNames;
use rigcast_engine::subject::Subject;

/// How long to wait before watching again after the watch failed (NATS away).
const REWATCH_AFTER: Duration = Duration::from_secs(1);

/// How often the entries' deadlines are checked (an expiry is reported this late at most).
const EXPIRY_CHECK: Duration = Duration::from_millis(250);

/// What discovery needs to start a relayed subject's source thread, which the supervisor
/// joins at shutdown like the others.
#[derive(Clone)]
pub struct LiveThreads {
    /// Set on shutdown.
    pub stop: Arc<AtomicBool>,
    /// Threads started after the start.
    pub threads: Arc<Mutex<Vec<std::thread::JoinHandle<()>>>>,
}

/// A relayed subject the watch already knows, by bucket key.
pub struct Known {
    /// Its source's change queue.
    pub changes: std::sync::mpsc::SyncSender<Change>,
    /// Its current entry (`None`: removed, or not published yet).
    entry: Option<SubjectEntry>,
    /// The bucket revision of the last put seen.
    revision: Option<u64>,
    /// When it expires unless put again (`None`: no current entry, or already expired).
    deadline: Option<Instant>,
}

impl Known {
    /// A relayed subject made at start, from the bucket's `revision` of its entry (`None`:
    /// not published yet). Its first heartbeat after that moves its deadline on.
    pub fn at_start(changes: std::sync::mpsc::SyncSender<Change>, revision: Option<u64>) -> Known {
        Known {
            changes,
            // Unknown here: the watch's first delivery of the same revision is not news.
            entry: None,
            revision,
            deadline: revision.map(|_| Instant::now() + ENTRY_MAX_AGE),
        }
    }

    /// Records a put at `revision` seen `now`; whether the subject's source must hear of it
    /// (a new entry, or the entry back after a removal or expiry). The same revision again
    /// (the watch restarted) is no sign of life.
    fn record_put(&mut self, entry: &SubjectEntry, revision: u64, now: Instant) -> bool {
        if self.revision == Some(revision) {
            if self.entry.is_none() && self.deadline.is_some() {
                self.entry = Some(entry.clone()); // made at start from this revision
            }
            return false;
        }
        self.revision = Some(revision);
        let live = self.deadline.is_some();
        self.deadline = Some(now + ENTRY_MAX_AGE);
        if live && self.entry.as_ref() == Some(entry) {
            return false; // a heartbeat
        }
        self.entry = Some(entry.clone());
        true
    }

    /// Records a delete or purge at `revision`.
    fn record_removal(&mut self, revision: u64) {
        self.entry = None;
        self.deadline = None;
        self.revision = Some(revision);
    }

    /// Whether a performer named it before its node published it, and no entry came yet.
    fn awaited(&self) -> bool {
        self.entry.is_none() && self.revision.is_none()
    }
}

/// Watches the bucket until shutdown; `known` are the relayed subjects made at start.
pub async fn run_discovery(
    cluster: Arc<Cluster>,
    mut known: HashMap<String, Known>,
    host: Discovery,
    live: LiveThreads,
    forwarder: Arc<Forwarder>,
) {
    let mut shutdown = host.feeds.shutdown.clone();
    let own = format!("{}.", cluster.config.site);
    let mut check = tokio::time::interval(EXPIRY_CHECK);
    check.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        let mut watch = match cluster.kv.watch_with_history(">").await {
            Ok(w) => w,
            Err(e) => {
                tracing::warn!("cluster: cannot watch the subject bucket: {e}; retrying");
                tokio::select! {
                    _ = shutdown.changed() => return,
                    _ = tokio::time::sleep(REWATCH_AFTER) => continue,
                }
            }
        };
        // Puts missed while the watch was down say nothing about the nodes: a fresh age.
        grant_grace(&mut known, Instant::now());
        loop {
            let entry = tokio::select! {
                biased;
                _ = shutdown.changed() => return,
                _ = check.tick() => {
                    expire(&mut known, Instant::now());
                    continue;
                }
                entry = watch.next() => entry,
            };
            // The watch ended or failed (NATS went away): watch again from the last values.
            let Some(Ok(entry)) = entry else { break };
            if entry.key.starts_with(&own) {
                continue;
            }
            match entry.operation {
                Operation::Put => match SubjectEntry::parse(&entry.value) {
                    Ok(e) => on_put(
                        &cluster,
                        &mut known,
                        e,
                        entry.revision,
                        &host,
                        (&live, &forwarder),
                    ),
                    Err(err) => tracing::warn!("cluster: entry {} skipped: {err}", entry.key),
                },
                Operation::Delete | Operation::Purge => {
                    if let Some(k) = known.get_mut(&entry.key) {
                        k.record_removal(entry.revision);
                        tell(k, Change::Removed);
                    }
                }
            }
        }
    }
}

/// Tells the source of every entry past its deadline that its node stopped answering.
fn expire(known: &mut HashMap<String, Known>, now: Instant) {
    for k in known.values_mut() {
        if k.deadline.is_some_and(|d| d <= now) {
            k.deadline = None;
            tell(k, Change::Expired);
        }
    }
}

/// Gives every current entry a full age from `now`.
fn grant_grace(known: &mut HashMap<String, Known>, now: Instant) {
    for k in known.values_mut().filter(|k| k.deadline.is_some()) {
        k.deadline = Some(now + ENTRY_MAX_AGE);
    }
}

/// Hands `change` to a relayed subject's source; a full queue drops it (see `CHANGES`).
fn tell(known: &Known, change: Change) {
    match known.changes.try_send(change) {
        Ok(()) | Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {}
    }
}

/// A put of `entry` at `revision`: news for a known subject's source, or a new subject.
fn on_put(
    cluster: &Cluster,
    known: &mut HashMap<String, Known>,
    entry: SubjectEntry,
    revision: u64,
    host: &Discovery,
    late: (&LiveThreads, &Forwarder),
) {
    let key = entry.key();
    let now = Instant::now();
    if let Some(k) = known.get_mut(&key) {
        let awaited = k.awaited();
        if k.record_put(&entry, revision, now) {
            if awaited {
                count_discovered(&host.feeds);
            }
            tell(k, Change::Entry(Box::new(entry)));
        }
        return;
    }
    match add_subject(cluster, &entry, host, late) {
        Ok(changes) => {
            count_discovered(&host.feeds);
            let found = Known {
                changes,
                entry: Some(entry),
                revision: Some(revision),
                deadline: Some(now + ENTRY_MAX_AGE),
            };
            known.insert(key, found);
        }
        Err(e) => tracing::warn!("cluster: cannot relay {}: {e:#}", entry.relayed_name()),
    }
}

/// A subject found while running (new, or one a performer waited for).
fn count_discovered(feeds: &Feeds) {
    feeds
        .stats
        .cluster_subjects_discovered
        .fetch_add(1, Ordering::Relaxed);
}

/// Makes a relayed subject of `entry` while the server runs.
fn add_subject(
    cluster: &Cluster,
    entry: &SubjectEntry,
    host: &Discovery,
    (live, forwarder): (&LiveThreads, &Forwarder),
) -> anyhow::Result<std::sync::mpsc::SyncSender<Change>> {
    let (source, remote) = RemoteSource::new(entry, cluster.config.lost_after())?;
    let skeleton = source.skeleton_arc();
    let feeds = &host.feeds;
    let taken: Vec<String> = feeds.subjects().iter().map(|s| s.info().name).collect();
    let name = rigcast_engine::subject_list::unique_name(&taken, entry.relayed_name());
    let mut watch_tx = None;
    let subject = feeds.subject_list.push(|id| {
        let (s, tx) = Subject::with_kind(
            id,
            name,
            skeleton,
            Some(SourceKind::Remote),
            Vec::new(),
            VmcBoneNames::default(),
        );
        watch_tx = Some(tx);
        Arc::new(s)
    });
    let tx = watch_tx.ok_or_else(|| anyhow::anyhow!("subject not made"))?;
    forwarder.add(
        subject.id,
        Origin {
            site: entry.site.clone(),
            name: entry.name.clone(),
        },
    );
    let frames = cluster
        .config
        .frame_subject(&entry.site, &super::token(&entry.name));
    tokio::spawn(run_relay(
        cluster.client.clone(),
        frames,
        subject.id,
        remote.frames,
        feeds.clone(),
    ));
    let ctx = LiveContext {
        subject: subject.clone(),
        feed: LiveFeed::Relayed(tx),
        subjects: feeds.subject_list.clone(),
        events: feeds.events.clone(),
        inbox: host.inbox.clone(),
        recorder: None,
        stop: live.stop.clone(),
    };
    let thread = std::thread::Builder::new()
        .name(format!("rigcast-live-{}", subject.id))
        .spawn(move || crate::live::run_live(Box::new(source), ctx))?;
    if let Ok(mut t) = live.threads.lock() {
        t.push(thread);
    }
    // Err only means no client is connected.
    let _ = feeds
        .events
        .send(rigcast_engine::events::Event::subjects_changed(
            &feeds.subjects(),
        ));
    // Fails only while no client listens; newcomers get every skeleton on connecting.
    let _ = feeds
        .events
        .send(rigcast_engine::events::Event::skeleton(&subject));
    Ok(remote.changes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(bones: usize) -> SubjectEntry {
        let bone = |i: usize| rigcast_protocol::control::BoneInfo {
            name: format!("b{i}"),
            parent: i.checked_sub(1).map(|p| p as u32),
            rest_translation: [0.0, 0.1, 0.0],
            rest_rotation: [0.0, 0.0, 0.0, 1.0],
            translated: i == 0,
        };
        SubjectEntry {
            site: "a".into(),
            name: "walk".into(),
            bones: (0..bones).map(bone).collect(),
            mapping: None,
        }
    }

    #[test]
    fn heartbeats_are_no_news_and_a_silent_entry_expires_once() {
        let (tx, rx) = std::sync::mpsc::sync_channel(8);
        let t0 = Instant::now();
        let mut known = HashMap::from([("a.walk".to_string(), Known::at_start(tx, Some(7)))]);
        let k = known.get_mut("a.walk").unwrap();
        // The watch's first delivery is the revision the subject was made from; then beats.
        assert!(!k.record_put(&entry(2), 7, t0));
        assert!(!k.record_put(&entry(2), 8, t0));
        assert!(!k.record_put(&entry(2), 9, t0 + ENTRY_MAX_AGE / 2));
        // A new skeleton is news.
        assert!(k.record_put(&entry(3), 10, t0 + ENTRY_MAX_AGE / 2));
        expire(&mut known, t0 + ENTRY_MAX_AGE);
        assert!(rx.try_recv().is_err(), "expired although put in time");
        expire(&mut known, t0 + ENTRY_MAX_AGE * 2);
        assert!(matches!(rx.try_recv(), Ok(Change::Expired)));
        expire(&mut known, t0 + ENTRY_MAX_AGE * 3);
        assert!(rx.try_recv().is_err(), "expired twice");
        // Its node back with the same entry: news (the source was told it is gone).
        let k = known.get_mut("a.walk").unwrap();
        assert!(k.record_put(&entry(3), 11, t0 + ENTRY_MAX_AGE * 3));
        // A watch restarted after an outage redelivers the same revision: no sign of life,
        // but the outage is no reason to expire it at once.
        grant_grace(&mut known, t0 + ENTRY_MAX_AGE * 5);
        expire(&mut known, t0 + ENTRY_MAX_AGE * 5);
        assert!(rx.try_recv().is_err());
    }

    #[test]
    fn a_subject_awaited_by_a_performer_takes_its_first_entry() {
        let (tx, _rx) = std::sync::mpsc::sync_channel(8);
        let mut k = Known::at_start(tx, None);
        assert!(k.awaited());
        assert!(k.record_put(&entry(2), 1, Instant::now()));
        assert!(!k.awaited());
        k.record_removal(2);
        assert!(!k.awaited(), "removed, not awaited");
        assert!(
            k.record_put(&entry(2), 3, Instant::now()),
            "back after removal"
        );
    }
}
