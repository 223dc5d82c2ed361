//! The checks off the tick that become events: a target's motion changing (idle graph,
//! resuming, live again), a fault starting or clearing, and the once-a-second
//! `source_status` report. Run by [`crate::machine::Engine`] at [`MOTION_POLL`]; reads the
//! counters the tick and the sources write, and the time it is given.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_protocol::TargetMotion;

use crate::events::Event;
use crate::fault::SeenFaults;
use crate::subject::Subject;
use crate::subject_list::SubjectList;

/// How often the targets' motions and the faults are looked at: a change reaches clients
/// within this and a tick, instead of waiting for the once-a-second report. Polling keeps the
/// tick itself free of it.
pub const MOTION_POLL: Duration = Duration::from_millis(50);

/// The longest time between two `source_status` reports.
pub const STATUS_EVERY: Duration = Duration::from_secs(1);

/// What the last look saw.
pub struct StatusWatch {
    subjects: Arc<SubjectList>,
    motions: Vec<(u32, TargetMotion)>,
    faults: SeenFaults,
    last_sent: Option<Instant>,
}

impl StatusWatch {
    /// Watches every subject of `subjects` (those the cluster adds later included).
    pub fn new(subjects: Arc<SubjectList>) -> StatusWatch {
        StatusWatch {
            subjects,
            motions: Vec::new(),
            faults: SeenFaults::new(),
            last_sent: None,
        }
    }

    /// Looks at `now`: tells (through `tell`) of faults that started, then sends
    /// `source_status` when a motion or a fault changed or [`STATUS_EVERY`] has passed.
    pub fn look(&mut self, now: Instant, mut tell: impl FnMut(Event)) {
        let subjects = self.subjects.snapshot();
        let changed = motions_changed(&subjects, &mut self.motions)
            | crate::fault::announce(&subjects, &mut self.faults, &mut tell);
        let due = self
            .last_sent
            .is_none_or(|t| now.saturating_duration_since(t) >= STATUS_EVERY);
        if changed || due {
            self.last_sent = Some(now);
            tell(Event::source_status(&subjects, now));
        }
    }
}

impl StatusWatch {
    /// Sends `source_status` now (a source's state changed), as of `now`.
    pub fn report(&mut self, now: Instant, mut tell: impl FnMut(Event)) {
        self.last_sent = Some(now);
        tell(Event::source_status(&self.subjects.snapshot(), now));
    }
}

/// Whether any target's motion differs from `seen` (then updated to the current ones).
fn motions_changed(subjects: &[Arc<Subject>], seen: &mut Vec<(u32, TargetMotion)>) -> bool {
    let current = subjects
        .iter()
        .filter(|s| s.is_target())
        .map(|s| (s.id, s.stats.motion.load()));
    if current.clone().eq(seen.iter().copied()) {
        return false;
    }
    seen.clear();
    seen.extend(current);
    true
}
