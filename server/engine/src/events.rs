//! What every client hears about as it happens, besides frames: typed events. Producers (live
//! sources, the mapper, calibration, the foot-plant sampler, the status task, cluster
//! discovery) say what happened in the server's own terms and know nothing of the protocol;
//! the host's `wire` module turns an event into its protocol message at the transport's edge (the
//! client sessions, the cluster's bucket entries).

use std::sync::Arc;

use crate::reports::{FootplantReport, HealthReport, MappingReport};
use crate::subject::{Subject, SubjectShape};

/// Control messages queued per client (mapping updates, skeleton changes, source status).
pub const EVENTS_CAPACITY: usize = 256;

/// Something clients are told about. Cheap to clone (the broadcast clones it per receiver).
#[derive(Debug, Clone)]
pub enum Event {
    /// The subject list or a subject's description changed: every subject's shape then.
    SubjectsChanged(Arc<[Arc<SubjectShape>]>),
    /// A subject has a new skeleton (its whole shape).
    Skeleton(Arc<SubjectShape>),
    /// A target's mapping was built.
    Mapping(Arc<MappingReport>),
    /// A target's planted feet changed.
    Footplants(Arc<FootplantReport>),
    /// The sources' health and the targets' motion (on a change, and about once a second).
    SourceStatus(Arc<HealthReport>),
    /// A subject faulted (a target's processing failed, or a source's task stopped).
    SubjectFaulted {
        /// The subject.
        subject: u32,
        /// Its name.
        name: String,
        /// Why.
        why: String,
    },
}

impl Event {
    /// [`Event::SubjectsChanged`] for `subjects` as they are now.
    pub fn subjects_changed(subjects: &[Arc<Subject>]) -> Event {
        Event::SubjectsChanged(subjects.iter().map(|s| s.shape()).collect())
    }

    /// [`Event::Skeleton`] for `subject`'s shape now.
    pub fn skeleton(subject: &Subject) -> Event {
        Event::Skeleton(subject.shape())
    }

    /// [`Event::SourceStatus`] for `subjects` as they are at `now`.
    pub fn source_status(subjects: &[Arc<Subject>], now: std::time::Instant) -> Event {
        Event::SourceStatus(Arc::new(crate::subject::health_report(subjects, now)))
    }

    /// Whether the event changes what a subject's cluster entry holds (its skeleton or its
    /// mapping).
    pub fn changes_an_entry(&self) -> bool {
        matches!(self, Event::Skeleton(_) | Event::Mapping(_))
    }
}
