//! Publishing this node's subjects: every frame the tick encodes goes out on core NATS as it
//! is (both protocol versions in one message), and each subject's entry (skeleton, mapping)
//! is kept current in the KV bucket. A node that stops cleanly deletes its entries, so the
//! others show its subjects lost at once and say why.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use rigcast_protocol::ServerMessage;
use tokio::sync::broadcast::error::RecvError;

use super::{Cluster, SubjectEntry};
use crate::state::ServerState;
use crate::subject::Subject;

/// Publishes every local (not relayed) subject of `state` until shutdown.
pub async fn run_publisher(cluster: Arc<Cluster>, state: Arc<ServerState>) {
    let mut frames = state.frames.subscribe();
    let mut events = state.events.subscribe();
    let mut shutdown = state.shutdown.clone();
    // By subject id: the NATS subject its frames go out on (None: relayed, not ours).
    let subjects: Vec<Option<async_nats::Subject>> = state
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
    put_entries(&cluster, &state).await;
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
                        state.stats.cluster_publish_errors.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(RecvError::Lagged(n)) => {
                    state.stats.cluster_publish_errors.fetch_add(n, Ordering::Relaxed);
                }
                Err(RecvError::Closed) => break,
            },
            received = events.recv() => match received {
                Ok(text) if changes_an_entry(&text) => put_entries(&cluster, &state).await,
                Ok(_) | Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => break,
            },
        }
    }
    remove_entries(&cluster, &state).await;
}

/// How long a stopping node spends on deleting its entries at most.
const REMOVE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

/// Deletes the entry of every local subject (on a clean stop).
async fn remove_entries(cluster: &Cluster, state: &ServerState) {
    let keys: Vec<String> = (state.subjects().iter())
        .filter(|s| !s.is_relayed())
        .filter_map(|s| entry_of(&cluster.config.site, s).map(|e| e.key()))
        .collect();
    let delete_all = async {
        for key in keys {
            // A failed delete leaves the entry: the others still see the frames stop.
            let _ = cluster.kv.delete(key).await;
        }
    };
    let _ = tokio::time::timeout(REMOVE_TIMEOUT, delete_all).await;
}

/// Whether a control message changes what the bucket holds (a skeleton or a mapping).
fn changes_an_entry(text: &str) -> bool {
    matches!(
        serde_json::from_str::<ServerMessage>(text),
        Ok(ServerMessage::Skeleton { .. } | ServerMessage::Mapping { .. })
    )
}

/// Writes the entry of every local subject (rare: at start and when a skeleton or mapping
/// changes). A failed write is reported and retried at the next change.
async fn put_entries(cluster: &Cluster, state: &ServerState) {
    for s in state.subjects().iter().filter(|s| !s.is_relayed()) {
        let Some(entry) = entry_of(&cluster.config.site, s) else {
            continue;
        };
        let Ok(value) = serde_json::to_vec(&entry) else {
            continue;
        };
        if let Err(e) = cluster.kv.put(entry.key(), value.into()).await {
            eprintln!(
                "warning: cluster: cannot publish subject {}: {e}",
                entry.name
            );
        }
    }
}

fn entry_of(site: &str, s: &Subject) -> Option<SubjectEntry> {
    let mapping = s.mapping_json.read().ok().and_then(|m| m.clone());
    SubjectEntry::from_messages(
        site,
        &s.info().name,
        &s.shape().skeleton_json,
        mapping.as_deref(),
    )
    .ok()
}
