//! Where the host's threads and tasks leave what the engine should learn of, for the host's
//! loop to pass on as [`Input`]s: each source's newest pose, source health changes, built
//! mappings and commands. Nobody here waits on the engine or on a client: a source's thread
//! holds its own door's lock only to copy a pose in, and the host's drain takes the same short
//! locks.
//!
//! ```text
//!  source thread ─SourceDoor::hand_over(pose)─▶ its door [newest pose · time · seq]  ─┐
//!  source thread ─SourceDoor::health(state)───▶ ┐                                     │
//!  mapper ───────Inbox::mapping(target, built)─▶├─ queue ─┐                           │
//!  sessions ─────Inbox::request(command)───────▶┘         ▼                           ▼
//!                          host loop: Inbox::drain ─▶ Input::{Health, Mapping, Command, Frame}
//!                                                        ─▶ Engine::handle_input
//! ```
//!
//! A door keeps one pose, the newest: a source faster than the engine's loop has its older
//! pose replaced (counted in the source's input rate all the same, as it was produced). Poses
//! are checked where they are handed over, so a refused one never replaces a good one. The
//! buffers are sized once, so handing over allocates nothing in steady state.
//!
//! Commands (`set_mapping`, `set_performer`, a source's skeleton change) reach the engine
//! here and leave it as [`crate::machine::Output::Build`] for the host's mapper; at most
//! [`COMMANDS_IN_FLIGHT`] requests from clients may be on their way at once (the mapper says
//! when it has taken one, [`Inbox::command_taken`]), beyond that [`Inbox::request`] answers
//! [`Busy`] instead of queueing without bound.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};

use rigcast_protocol::SourceState;
use rigcast_retarget::Pose;

use crate::clock::TickTime;
use crate::machine::Input;
use crate::performer::BuiltMapping;
use crate::subject::Subject;
use crate::tick::EngineCommand;

/// How many commands may be on their way to the mapper (handed in, not yet taken by it)
/// before a client's request is refused as [`Busy`].
pub const COMMANDS_IN_FLIGHT: usize = 64;

/// A client's request was refused: [`COMMANDS_IN_FLIGHT`] commands are still on their way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Busy;

/// What the engine should learn of, left by the host's threads and tasks (cheap to clone:
/// every clone is the same inbox).
#[derive(Clone)]
pub struct Inbox {
    shared: Arc<Shared>,
}

struct Shared {
    doors: RwLock<Vec<Arc<Door>>>,
    queue: Mutex<Queued>,
    /// Commands handed in that the mapper has not taken yet.
    in_flight: AtomicUsize,
    /// Tells the host's loop that something came in (it then drains).
    waker: Box<dyn Fn() + Send + Sync>,
}

/// What waits in the order it came.
#[derive(Default)]
struct Queued {
    items: VecDeque<Item>,
}

enum Item {
    Health(u32, SourceState),
    /// Boxed: a mapping is large and rare, the queue's other items small.
    Mapping(u32, Box<BuiltMapping>),
    Command(EngineCommand),
}

/// One source's newest pose.
struct Door {
    subject: Arc<Subject>,
    /// Whether a new pose should bring the tick forward (the host's loop is woken for it).
    wakes: bool,
    /// The last state handed over, as [`state_code`] numbers it (0: none yet).
    state: AtomicU8,
    pending: Mutex<Pending>,
}

struct Pending {
    /// The newest pose, not yet taken while `fresh`.
    pose: Pose,
    /// Where a pose is copied and checked before it replaces `pose`.
    scratch: Pose,
    time: Option<TickTime>,
    capture_nanos: u64,
    seq: u64,
    fresh: bool,
}

/// A source's way into the engine (held by its thread or task).
pub struct SourceDoor {
    door: Arc<Door>,
    inbox: Inbox,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A source state as a number for the door's atomic (0 is "none yet").
fn state_code(s: SourceState) -> u8 {
    match s {
        SourceState::Connecting => 1,
        SourceState::Live => 2,
        SourceState::Lost => 3,
        SourceState::Finished => 4,
        SourceState::Failed => 5,
    }
}

impl Inbox {
    /// An empty inbox; `waker` is called (from any thread) when something comes in that the
    /// host's loop should pass on now rather than at its next wake-up.
    pub fn new(waker: impl Fn() + Send + Sync + 'static) -> Inbox {
        Inbox {
            shared: Arc::new(Shared {
                doors: RwLock::new(Vec::new()),
                queue: Mutex::new(Queued::default()),
                in_flight: AtomicUsize::new(0),
                waker: Box::new(waker),
            }),
        }
    }

    /// A door for source `subject`'s poses and health; with `wakes`, each pose handed over
    /// wakes the host's loop at once (a camera: the engine brings the tick forward), else the
    /// loop takes it when it next runs (before any tick). The engine must be fed the
    /// subject's slot ([`crate::Engine::feed`]) to take its poses.
    pub fn door(&self, subject: Arc<Subject>, wakes: bool) -> SourceDoor {
        let rest = subject.skeleton().rest_pose();
        let door = Arc::new(Door {
            subject,
            wakes,
            state: AtomicU8::new(0),
            pending: Mutex::new(Pending {
                scratch: rest.clone(),
                pose: rest,
                time: None,
                capture_nanos: 0,
                seq: 0,
                fresh: false,
            }),
        });
        let mut doors = self.shared.doors.write().unwrap_or_else(|p| p.into_inner());
        doors.retain(|d| d.subject.id != door.subject.id);
        doors.push(door.clone());
        SourceDoor {
            door,
            inbox: self.clone(),
        }
    }

    /// A mapping for `target` was built (by the host's mapper).
    pub fn mapping(&self, target: u32, built: BuiltMapping) {
        self.push(Item::Mapping(target, Box::new(built)));
    }

    /// A client's request (`set_mapping`, `set_performer`); refused while
    /// [`COMMANDS_IN_FLIGHT`] are on their way.
    pub fn request(&self, command: EngineCommand) -> Result<(), Busy> {
        let taken = self
            .shared
            .in_flight
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
                (n < COMMANDS_IN_FLIGHT).then_some(n + 1)
            });
        if taken.is_err() {
            return Err(Busy);
        }
        self.push(Item::Command(command));
        Ok(())
    }

    /// A command that must not be refused (a source's skeleton changed: its sources send
    /// these at most once a second each). Counted in flight like a request.
    pub fn notice(&self, command: EngineCommand) {
        self.shared.in_flight.fetch_add(1, Ordering::Relaxed);
        self.push(Item::Command(command));
    }

    /// The mapper has taken one command the engine passed on (frees a place for a request).
    pub fn command_taken(&self) {
        // Err: nothing was counted (a command that did not come through here).
        let _ = self
            .shared
            .in_flight
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| n.checked_sub(1));
    }

    fn push(&self, item: Item) {
        lock(&self.shared.queue).items.push_back(item);
        (self.shared.waker)();
    }

    /// Passes everything waiting to `take` as [`Input`]s, in order: health, mappings and
    /// commands as they came, then each source's newest pose (so a skeleton change's command
    /// comes before the poses on the new skeleton). Allocates nothing.
    pub fn drain(&self, mut take: impl FnMut(Input<'_>)) {
        loop {
            // Popped under the lock, passed on without it.
            let Some(item) = lock(&self.shared.queue).items.pop_front() else {
                break;
            };
            take(match item {
                Item::Health(subject, state) => Input::Health { subject, state },
                Item::Mapping(target, built) => Input::Mapping {
                    target,
                    built: *built,
                },
                Item::Command(command) => Input::Command(command),
            });
        }
        let doors = self.shared.doors.read().unwrap_or_else(|p| p.into_inner());
        for door in doors.iter() {
            let mut p = lock(&door.pending);
            let Some(time) = p.time.filter(|_| p.fresh) else {
                continue;
            };
            p.fresh = false;
            // The source's thread waits for this copy at most (it is the door's only other
            // user).
            take(Input::Frame {
                subject: door.subject.id,
                time,
                capture_nanos: p.capture_nanos,
                seq: p.seq,
                pose: &p.pose,
            });
        }
    }
}

impl SourceDoor {
    /// The source subject.
    pub fn subject(&self) -> &Arc<Subject> {
        &self.door.subject
    }

    /// Hands over the source's newest pose, produced as frame `seq` of the source (0: the
    /// next one), captured at `capture_nanos` (0: at `time`), handed over at `time`. It is
    /// checked here (refused: counted on the subject, `false` returned) and replaces a pose
    /// not yet taken. Allocates nothing unless the skeleton's size changed.
    pub fn hand_over(&self, time: TickTime, seq: u64, capture_nanos: u64, pose: &Pose) -> bool {
        let door = &self.door;
        let mut p = lock(&door.pending);
        if p.scratch.num_bones() == pose.num_bones() {
            p.scratch.copy_from(pose);
        } else {
            // Only after a skeleton change.
            p.scratch = pose.clone();
        }
        if !door.subject.admit(&mut p.scratch, time.instant) {
            return false;
        }
        if p.fresh {
            // Replaced before the engine took it: still a frame the source produced.
            if let Some(t) = p.time {
                door.subject.stats.input.tick(t.instant);
            }
        }
        let Pending { pose, scratch, .. } = &mut *p;
        std::mem::swap(pose, scratch);
        p.time = Some(time);
        p.capture_nanos = capture_nanos;
        p.seq = seq;
        p.fresh = true;
        drop(p);
        if door.wakes {
            (self.inbox.shared.waker)();
        }
        true
    }

    /// The source's state now; passed on only when it differs from the last one given.
    pub fn health(&self, state: SourceState) {
        let code = state_code(state);
        if self.door.state.swap(code, Ordering::Relaxed) != code {
            self.inbox.push(Item::Health(self.door.subject.id, state));
        }
    }

    /// The inbox this door leads to.
    pub fn inbox(&self) -> &Inbox {
        &self.inbox
    }
}
