//! The subject list as the listener, client sessions, live threads and status see it. It
//! grows while the server runs when the cluster finds another node's subject, so readers take
//! a snapshot (an `Arc` clone) and never hold the lock. The tick, the mapper, the recorder
//! and the foot-plant sampler keep the list of the start: subjects added later are relayed
//! ones, which none of them handles.

use std::sync::{Arc, RwLock};

use crate::subject::Subject;

/// Subjects in id order (id = index); only ever appended to.
#[derive(Debug)]
pub struct SubjectList {
    all: RwLock<Arc<Vec<Arc<Subject>>>>,
}

impl SubjectList {
    /// The list of the start.
    pub fn new(subjects: Arc<Vec<Arc<Subject>>>) -> SubjectList {
        SubjectList {
            all: RwLock::new(subjects),
        }
    }

    /// The subjects now.
    pub fn snapshot(&self) -> Arc<Vec<Arc<Subject>>> {
        match self.all.read() {
            Ok(g) => g.clone(),
            Err(p) => p.into_inner().clone(),
        }
    }

    /// A subject by id (ids are positions in the list; a subject found there carries it).
    pub fn get(&self, id: u32) -> Option<Arc<Subject>> {
        self.snapshot()
            .get(id as usize)
            .filter(|s| s.id == id)
            .cloned()
    }

    /// Appends the subject `make` builds for the next id; returns it.
    pub fn push(&self, make: impl FnOnce(u32) -> Arc<Subject>) -> Arc<Subject> {
        let mut guard = match self.all.write() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let subject = make(guard.len() as u32);
        let mut next = Vec::with_capacity(guard.len() + 1);
        next.extend(guard.iter().cloned());
        next.push(subject.clone());
        *guard = Arc::new(next);
        subject
    }
}

/// `name`, or `name-2`, `name-3`… when taken.
pub fn unique_name(taken: &[String], name: String) -> String {
    if !taken.contains(&name) {
        return name;
    }
    (2..)
        .map(|i| format!("{name}-{i}"))
        .find(|n| !taken.contains(n))
        .unwrap_or(name)
}
