//! Faults that must not stop the show: a panic in one subject's processing is caught where
//! that subject is run (its performer's tick, its source's task or thread), recorded on the
//! subject and told to clients, and the rest of the server goes on.
//!
//! ```text
//!  performer tick ─catch_unwind─▶ fault on the target's stats ─▶ status task (50 ms poll)
//!                                  retried every FAULT_RETRY      ─▶ `error` subject_faulted
//!  replay task / live thread ─catch_unwind─▶ source `failed` (detail: why) ─▶ source_status
//! ```

use std::any::Any;
use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::time::Duration;

use futures_util::FutureExt;
use tokio::sync::broadcast;

use crate::subject::Subject;

/// How long a faulted performer waits before it is tried again (a fault that repeats on
/// every tick would otherwise print a panic report 60 times a second).
pub const FAULT_RETRY: Duration = Duration::from_millis(250);

/// The message of a caught panic (its payload is a `&str` or a `String` for `panic!` with a
/// message; anything else is unnamed).
pub fn panic_text(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic without a message".to_string()
    }
}

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

fn source_failed(subject: &Subject, payload: &(dyn Any + Send)) {
    let why = format!("stopped on an internal error: {}", panic_text(payload));
    tracing::error!("source {}: {why}", subject.info().name);
    subject.health.fail(why);
}

/// What [`announce`] last saw of one subject: its fault count and whether it is faulted or
/// failed now.
pub type SeenFaults = Vec<(u32, u64, bool)>;

/// Tells clients of faults that started since the last call (an `error` with the subject, code
/// `subject_faulted`) and returns whether any subject's fault state changed (a fault started
/// or cleared, a source failed), so the caller sends a fresh `source_status`.
pub fn announce(
    subjects: &[Arc<Subject>],
    seen: &mut SeenFaults,
    events: &broadcast::Sender<crate::events::Event>,
) -> bool {
    let mut changed = false;
    for s in subjects {
        let total = s
            .stats
            .faults_total
            .load(std::sync::atomic::Ordering::Relaxed);
        let failed = s.health.failure();
        let fault = s.stats.fault().or(failed);
        let now = (s.id, total, fault.is_some());
        match seen.iter_mut().find(|e| e.0 == s.id) {
            Some(e) if *e == now => continue,
            Some(e) => *e = now,
            None if !now.2 && total == 0 => {
                seen.push(now);
                continue;
            }
            None => seen.push(now),
        }
        changed = true;
        if let Some(why) = fault {
            let event = crate::events::Event::SubjectFaulted {
                subject: s.id,
                name: s.info().name,
                why,
            };
            // Err only means no client is connected.
            let _ = events.send(event);
        }
    }
    changed
}
