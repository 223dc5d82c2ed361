//! Publishing this node's subjects: every frame the tick encodes goes out on core NATS as it
//! is (both protocol versions in one message), and each subject's entry (skeleton, mapping)
//! is kept current in the KV bucket by its own task ([`run_entries`], so a slow JetStream
//! never holds up the frames). A node that stops cleanly deletes its entries, so the others
//! show its subjects lost at once and say why; a running node puts them again every
//! [`HEARTBEAT`], so the entries of a node that was killed age out of the bucket
//! ([`super::ENTRY_MAX_AGE`]) and the others say it stopped answering.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use tokio::sync::broadcast::error::RecvError;
use tokio_tungstenite::tungstenite::Bytes;

use super::{Cluster, SubjectEntry, HEARTBEAT};
use crate::state::Feeds;
use rigcast_engine::subject::Subject;

/// Publishes every local (not relayed) subject of `feeds` until shutdown.
pub async fn run_publisher(cluster: Arc<Cluster>, feeds: Feeds) {
    let mut frames = feeds.frames.subscribe();
    let mut shutdown = feeds.shutdown.clone();
    // By subject id: the NATS subject its frames go out on (None: relayed, not ours).
    let subjects: Vec<Option<async_nats::Subject>> = feeds
        .subjects()
        .iter()
        .map(|s| {
            (!s.is_relayed()).then(|| {
                let key = super::token(&s.info().name);
                cluster
                    .config
                    .frame_subject(&cluster.config.site, &key)
                    .into()
            })
        })
        .collect();
    loop {
        tokio::select! {
            biased;
            _ = shutdown.changed() => break,
            received = frames.recv() => match received {
                Ok(frame) => {
                    let Some(Some(subject)) = subjects.get(frame.subject as usize) else {
                        continue;
                    };
                    // Queued in the client's buffer, written by its own task: never waits on
                    // the network here.
                    if cluster.client.publish(subject.clone(), frame.bytes.clone()).await.is_err() {
                        feeds.stats.cluster_publish_errors.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(RecvError::Lagged(n)) => {
                    feeds.stats.cluster_publish_errors.fetch_add(n, Ordering::Relaxed);
                }
                Err(RecvError::Closed) => break,
            },
        }
    }
}

/// Keeps the entry of every local subject in the bucket until shutdown: put at start, when a
/// skeleton or mapping changes, and every [`HEARTBEAT`]; deleted on a clean stop.
pub async fn run_entries(cluster: Arc<Cluster>, feeds: Feeds) {
    let mut events = feeds.events.subscribe();
    let mut shutdown = feeds.shutdown.clone();
    let mut entries = entries_of(&cluster, &feeds);
    let mut heartbeat = tokio::time::interval(HEARTBEAT);
    // A late beat (loaded machine) is followed by the next one a whole period later, not
    // by a burst.
    heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut failing = false;
    loop {
        tokio::select! {
            biased;
            _ = shutdown.changed() => break,
            received = events.recv() => match received {
                Ok(event) if event.changes_an_entry() => {
                    entries = entries_of(&cluster, &feeds);
                    failing = put_entries(&cluster, &entries, failing).await;
                }
                Ok(_) | Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => break,
            },
            _ = heartbeat.tick() => failing = put_entries(&cluster, &entries, failing).await,
        }
    }
    remove_entries(&cluster, &entries).await;
}

/// How long a stopping node spends on deleting its entries at most.
const REMOVE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

/// Deletes the entry of every local subject (on a clean stop).
async fn remove_entries(cluster: &Cluster, entries: &[(String, Bytes)]) {
    let delete_all = async {
        for (key, _) in entries {
            // A failed delete leaves the entry: the others still see the frames stop.
            let _ = cluster.kv.delete(key).await;
        }
    };
    // A NATS server that does not answer must not hold up shutdown; the other nodes take an
    // entry left behind as lost once it goes unrefreshed for `ENTRY_MAX_AGE`.
    let _ = tokio::time::timeout(REMOVE_TIMEOUT, delete_all).await;
}

/// The bucket key and value of every local subject (at start and when a skeleton or mapping
/// changes; the heartbeat puts these again).
fn entries_of(cluster: &Cluster, feeds: &Feeds) -> Vec<(String, Bytes)> {
    (feeds.subjects().iter())
        .filter(|s| !s.is_relayed())
        .filter_map(|s| entry_of(&cluster.config.site, s))
        .filter_map(|e| Some((e.key(), serde_json::to_vec(&e).ok()?.into())))
        .collect()
}

/// Puts `entries`; whether a put failed. A failure is reported when it starts (`failing`:
/// the previous round failed), not once a heartbeat, and retried at the next one.
async fn put_entries(cluster: &Cluster, entries: &[(String, Bytes)], failing: bool) -> bool {
    let mut failed = false;
    for (key, value) in entries {
        if let Err(e) = cluster.kv.put(key.clone(), value.clone()).await {
            if !failing && !failed {
                tracing::warn!("cluster: cannot publish subject entry {key}: {e}; retrying");
            }
            failed = true;
        }
    }
    failed
}

fn entry_of(site: &str, s: &Subject) -> Option<SubjectEntry> {
    let mapping = match s.mapping() {
        Some(report) => Some(serde_json::to_value(crate::wire::mapping(&report)).ok()?),
        None => None,
    };
    Some(SubjectEntry::new(
        site,
        &s.info().name,
        crate::wire::bones(&s.shape()),
        mapping,
    ))
}
