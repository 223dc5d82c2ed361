//! Discovery: this node watches the subject bucket for as long as it runs, so another node
//! that starts later, a subject that appears, or one whose skeleton changes is picked up
//! without a restart here.
//!
//! ```text
//!  KV watch "{ns}_subjects" (last value per key, then every change)
//!    put, new key      ─▶ a new relayed subject: relay task + RemoteSource thread, clients
//!                         told (`subjects_changed`, `skeleton`)
//!    put, known key    ─▶ Change::Entry ─▶ its RemoteSource (new skeleton, or back after a
//!                         removal)
//!    delete / purge    ─▶ Change::Removed ─▶ the subject is lost ("removed from the cluster")
//! ```
//!
//! Subjects are never taken away here (clients keep their ids); a removed one stays, lost,
//! until its node puts it again. Only relayed subjects are added: a performer of this node
//! keeps the sources it was started with.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::TrySendError;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use async_nats::jetstream::kv::Operation;
use futures_util::StreamExt;
use rigcast_protocol::{ServerMessage, SourceKind};

use super::{run_relay, Change, Cluster, Origin, RemoteSource, SubjectEntry};
use crate::config::VmcBoneNames;
use crate::live::LiveContext;
use crate::state::ServerState;
use crate::subject::Subject;

/// How long to wait before watching again after the watch failed (NATS away).
const REWATCH_AFTER: Duration = Duration::from_secs(1);

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
}

/// Watches the bucket until shutdown; `known` are the relayed subjects made at start.
pub async fn run_discovery(
    cluster: Arc<Cluster>,
    mut known: HashMap<String, Known>,
    state: Arc<ServerState>,
    live: LiveThreads,
) {
    let mut shutdown = state.shutdown.clone();
    let own = format!("{}.", cluster.config.site);
    loop {
        let mut watch = match cluster.kv.watch_with_history(">").await {
            Ok(w) => w,
            Err(e) => {
                eprintln!("warning: cluster: cannot watch the subject bucket: {e}; retrying");
                tokio::select! {
                    _ = shutdown.changed() => return,
                    _ = tokio::time::sleep(REWATCH_AFTER) => continue,
                }
            }
        };
        loop {
            let entry = tokio::select! {
                biased;
                _ = shutdown.changed() => return,
                entry = watch.next() => entry,
            };
            // The watch ended or failed (NATS went away): watch again from the last values.
            let Some(Ok(entry)) = entry else { break };
            if entry.key.starts_with(&own) {
                continue;
            }
            match entry.operation {
                Operation::Put => match SubjectEntry::parse(&entry.value) {
                    Ok(e) => on_put(&cluster, &mut known, e, &state, &live),
                    Err(err) => eprintln!("warning: cluster: entry {} skipped: {err}", entry.key),
                },
                Operation::Delete | Operation::Purge => {
                    if let Some(k) = known.get(&entry.key) {
                        tell(k, Change::Removed);
                    }
                }
            }
        }
    }
}

/// Hands `change` to a relayed subject's source; a full queue drops it (see `CHANGES`).
fn tell(known: &Known, change: Change) {
    match known.changes.try_send(change) {
        Ok(()) | Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {}
    }
}

fn on_put(
    cluster: &Cluster,
    known: &mut HashMap<String, Known>,
    entry: SubjectEntry,
    state: &Arc<ServerState>,
    live: &LiveThreads,
) {
    let key = entry.key();
    if let Some(k) = known.get(&key) {
        tell(k, Change::Entry(Box::new(entry)));
        return;
    }
    match add_subject(cluster, &entry, state, live) {
        Ok(k) => {
            state
                .stats
                .cluster_subjects_discovered
                .fetch_add(1, Ordering::Relaxed);
            known.insert(key, k);
        }
        Err(e) => eprintln!(
            "warning: cluster: cannot relay {}: {e:#}",
            entry.relayed_name()
        ),
    }
}

/// Makes a relayed subject of `entry` while the server runs.
fn add_subject(
    cluster: &Cluster,
    entry: &SubjectEntry,
    state: &Arc<ServerState>,
    live: &LiveThreads,
) -> anyhow::Result<Known> {
    let (source, feeds) = RemoteSource::new(entry, cluster.config.lost_after())?;
    let skeleton = source.skeleton_arc();
    let taken: Vec<String> = state.subjects().iter().map(|s| s.info().name).collect();
    let name = crate::boot::unique_name(&taken, entry.relayed_name());
    let mut watch_tx = None;
    let subject = state.subject_list.push(|id| {
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
    if let Some(f) = &state.forwarder {
        f.add(
            subject.id,
            Origin {
                site: entry.site.clone(),
                name: entry.name.clone(),
            },
        );
    }
    let frames = cluster
        .config
        .frame_subject(&entry.site, &super::token(&entry.name));
    tokio::spawn(run_relay(
        cluster.client.clone(),
        frames,
        subject.id,
        feeds.frames,
        state.clone(),
    ));
    let ctx = LiveContext {
        subject: subject.clone(),
        tx,
        subjects: state.subject_list.clone(),
        events: state.events.clone(),
        commands: state.commands.clone(),
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
    let _ = state.events.send(
        ServerMessage::SubjectsChanged {
            subjects: state.subject_infos(),
        }
        .to_json(),
    );
    let _ = state.events.send(subject.shape().skeleton_json.clone());
    Ok(Known {
        changes: feeds.changes,
    })
}
