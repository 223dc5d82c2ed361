//! The host's guards around its source tasks and threads (a panic marks the source failed
//! instead of leaving it `live` with nothing coming); the engine announces faults (its
//! `status` checks) and what the guards share with it is `rigcast_engine::fault`.

use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::sync::Arc;

use futures_util::FutureExt;

use rigcast_engine::fault::source_failed;

use rigcast_engine::subject::Subject;

/// Runs a source's task; a panic marks the source `failed` (with why) instead of leaving it
/// `live` with nothing coming. Clients hear of it from the engine's status checks.
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
