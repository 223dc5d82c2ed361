//! The host's guards around its source tasks and threads (a panic marks the source failed
//! instead of leaving it `live` with nothing coming), and the status task's announcement of
//! faults; what they share with the engine is `rigcast_engine::fault`, re-exported here.

use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::sync::Arc;

use futures_util::FutureExt;
use tokio::sync::broadcast;

pub use rigcast_engine::fault::{panic_text, source_failed, SeenFaults, FAULT_RETRY};

use crate::events::Event;
use crate::subject::Subject;

/// Runs a source's task; a panic marks the source `failed` (with why) instead of leaving it
/// `live` with nothing coming. Clients hear of it from the status task ([`announce`]).
pub async fn guard_source_task(task: impl Future<Output = ()>, subject: Arc<Subject>) {
    if let Err(payload) = AssertUnwindSafe(task).catch_unwind().await {
        source_failed(&subject, &*payload);
    }
}

/// Runs a live source's thread body, as [`guard_source_task`].
pub fn guard_source_thread(run: impl FnOnce(), subject: Arc<Subject>) {
    if let Err(payload) = std::panic::catch_unwind(AssertUnwindSafe(run)) {
        source_failed(&subject, &*payload);
    }
}

/// [`rigcast_engine::fault::announce`] onto the clients' event broadcast.
pub fn announce(
    subjects: &[Arc<Subject>],
    seen: &mut SeenFaults,
    events: &broadcast::Sender<Event>,
) -> bool {
    rigcast_engine::fault::announce(subjects, seen, |event| {
        // Err only means no client is connected.
        let _ = events.send(event);
    })
}
