//! Faults that must not stop the show: a panic in one subject's processing is caught where
//! that subject is run (its performer's tick, its source's task or thread), recorded on the
//! subject and told to clients, and the rest of the server goes on.
//!
//! ```text
//!  performer tick ─catch_unwind─▶ fault on the target's stats ─▶ status task (50 ms poll)
//!                                  retried every FAULT_RETRY      ─▶ `error` subject_faulted
//!  replay task / live thread ─catch_unwind─▶ source `failed` (detail: why) ─▶ source_status
//! ```
//!
//! The host guards its tasks and threads and polls [`announce`]; this module holds what the
//! engine and the host share.

use std::any::Any;
use std::sync::Arc;
use std::time::Duration;

use crate::events::Event;
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

/// Marks `subject` failed for good after its task or thread panicked with `payload`.
pub fn source_failed(subject: &Subject, payload: &(dyn Any + Send)) {
    let why = format!("stopped on an internal error: {}", panic_text(payload));
    tracing::error!("source {}: {why}", subject.info().name);
    subject.health.fail(why);
}

/// What [`announce`] last saw of one subject: its fault count and whether it is faulted or
/// failed now.
pub type SeenFaults = Vec<(u32, u64, bool)>;

/// Tells clients (through `tell`) of faults that started since the last call (an `error` with
/// the subject, code `subject_faulted`) and returns whether any subject's fault state changed (a fault started
/// or cleared, a source failed), so the caller sends a fresh `source_status`.
pub fn announce(
    subjects: &[Arc<Subject>],
    seen: &mut SeenFaults,
    mut tell: impl FnMut(Event),
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
            tell(Event::SubjectFaulted {
                subject: s.id,
                name: s.info().name,
                why,
            });
        }
    }
    changed
}
