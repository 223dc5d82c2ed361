//! The engine as one state machine: fed [`Input`]s (the time, source poses, health, built
//! mappings, commands), it yields [`Output`]s (frames, VMC datagrams, typed events, mappings
//! to build, and when it next wants to run). It reads no clock and does no IO; the host is a
//! loop that sleeps until the wake-up it was given or an input arrives. The host's threads
//! leave their inputs in an [`crate::inbox::Inbox`], which the loop drains into
//! [`Engine::handle_input`].
//!
//! ```text
//!  host loop ──handle_input(Timeout(now) | Frame | Health | Mapping | Command)──▶ Engine
//!      ▲                                                                               │
//!      └──poll_output() until Timeout(at): Datagram → UDP, Frame → clients,  ◀─────────┘
//!         Event → clients, Build → the mapper, Ticked → the tick-time counters;
//!         then sleep until `at` or the inbox wakes it
//! ```
//!
//! A due tick runs in two steps so that its frames carry when they were encoded, as the
//! protocol defines `send_nanos`: `Timeout(t)` runs the performers at `t`, and the engine
//! then asks for another `Timeout` at once; the time that one brings stamps the encoded
//! frames. A test on a simulated clock passes the same time twice. Off the tick, at their
//! own rates: the planted-feet report ([`FOOTPLANT_EVERY`]) and the faults, motions and
//! `source_status` ([`crate::status`]).

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_protocol::SourceState;
use rigcast_retarget::Pose;

use crate::clock::TickTime;
use crate::events::Event;
use crate::footplants::FootplantSampler;
use crate::performer::BuiltMapping;
use crate::schedule::{Every, TickSchedule};
use crate::slot::FrameWriter;
use crate::status::{StatusWatch, MOTION_POLL};
use crate::subject_list::SubjectList;
use crate::tick::{EngineCommand, OutFrame, TickContext, TickOutput, Ticker};

/// How often the planted feet are compared with the last report (plants change a few times a
/// second while walking; 30 Hz keeps a marker within two display frames of the lock).
pub const FOOTPLANT_EVERY: Duration = Duration::from_nanos(1_000_000_000 / 30);

/// What the engine is fed.
#[derive(Debug)]
pub enum Input<'a> {
    /// The time now: whatever is due runs (a tick, the encoding of a tick that performed,
    /// the checks off the tick).
    Timeout(TickTime),
    /// A source's new pose, for a source whose slot the engine holds (see [`Engine::feed`]).
    Frame {
        /// The source subject.
        subject: u32,
        /// When it was handed over.
        time: TickTime,
        /// When it was captured, Unix ns (0: at `time`).
        capture_nanos: u64,
        /// The source's own number for it (0: the one after the last): the frame carries
        /// the larger of this and the last one's + 1, so a gap shows frames the engine
        /// never took.
        seq: u64,
        /// The pose, on the subject's skeleton.
        pose: &'a Pose,
    },
    /// A source's health changed.
    Health {
        /// The source subject.
        subject: u32,
        /// Its state now.
        state: SourceState,
    },
    /// A target's mapping was built (the tick takes it at its next run).
    Mapping {
        /// The target subject.
        target: u32,
        /// The mapping.
        built: BuiltMapping,
    },
    /// A request from a client or a source: a mapping to rebuild. Building reads whole
    /// skeletons and may take long, so it is not done here: the engine takes note (a source
    /// whose skeleton changed has its poses checked against the new one) and passes it on as
    /// [`Output::Build`].
    Command(EngineCommand),
}

/// What the engine hands out, in order: datagrams, frames, events, the end of a tick, then
/// when it next wants to run.
#[derive(Debug)]
pub enum Output<'a> {
    /// One VMC bundle (≤ 1500 bytes) for the receiver at `to`.
    Datagram {
        /// The receiver.
        to: SocketAddr,
        /// The bundle (valid until the next call).
        bundle: &'a [u8],
    },
    /// One subject's frame of a tick.
    Frame(OutFrame),
    /// Something clients are told about.
    Event(Event),
    /// A mapping to build off the realtime path (the host's mapper); it comes back as
    /// [`Input::Mapping`].
    Build(EngineCommand),
    /// The tick that started at this time has handed out everything.
    Ticked(TickTime),
    /// Nothing more now: call [`Engine::handle_input`] with [`Input::Timeout`] at this time
    /// (or earlier, with another input).
    Timeout(Instant),
}

/// What an engine runs.
pub struct EngineParts {
    /// The tick's subjects, VMC receivers and performers.
    pub tick: TickContext,
    /// Ticks per second.
    pub rate_hz: f64,
    /// Every subject, those added while running included (for `source_status`).
    pub subjects: Arc<SubjectList>,
}

/// Outputs waiting for [`Engine::poll_output`]; buffers are reused.
#[derive(Default)]
struct Queue {
    bundles: Vec<u8>,
    datagrams: VecDeque<(SocketAddr, usize, usize)>,
    frames: VecDeque<OutFrame>,
    events: VecDeque<Event>,
    builds: VecDeque<EngineCommand>,
    ticked: Option<TickTime>,
}

impl TickOutput for Queue {
    fn frame(&mut self, frame: OutFrame) {
        self.frames.push_back(frame);
    }

    fn datagram(&mut self, to: SocketAddr, bundle: &[u8]) {
        let start = self.bundles.len();
        self.bundles.extend_from_slice(bundle);
        self.datagrams.push_back((to, start, self.bundles.len()));
    }
}

/// A source the engine writes the poses of.
struct Fed {
    subject: u32,
    writer: FrameWriter,
    wakes: bool,
    /// The pose given, checked here before it reaches the slot (sized once).
    checked: Pose,
}

/// The engine: the tick, its timetable, the checks off the tick and the outputs waiting.
pub struct Engine {
    ticker: Ticker,
    schedule: TickSchedule,
    /// A tick that performed at this time and waits to be encoded.
    performed: Option<TickTime>,
    footplants: FootplantSampler,
    footplant_every: Every,
    status: StatusWatch,
    status_every: Every,
    fed: Vec<Fed>,
    queue: Queue,
    /// The latest time given (the start before any).
    now: Instant,
}

impl Engine {
    /// An engine over `parts` whose first tick is due at `start`.
    pub fn new(parts: EngineParts, start: Instant) -> Engine {
        let footplants = FootplantSampler::new(&parts.tick.subjects);
        let rate = if parts.rate_hz.is_finite() && parts.rate_hz > 0.0 {
            parts.rate_hz
        } else {
            60.0
        };
        Engine {
            ticker: Ticker::new(parts.tick),
            schedule: TickSchedule::new(Duration::from_secs_f64(1.0 / rate)),
            performed: None,
            footplants,
            footplant_every: Every::new(FOOTPLANT_EVERY),
            status: StatusWatch::new(parts.subjects),
            status_every: Every::new(MOTION_POLL),
            fed: Vec::new(),
            queue: Queue::default(),
            now: start,
        }
    }

    /// Poses of source `subject` come in as [`Input::Frame`] and are written to `writer`
    /// (its slot); with `wakes` (a camera), each brings the tick forward to when it was
    /// handed over.
    pub fn feed(&mut self, subject: u32, writer: FrameWriter, wakes: bool) {
        self.fed.retain(|f| f.subject != subject);
        let checked = writer.borrow().pose.clone();
        self.fed.push(Fed {
            subject,
            writer,
            wakes,
            checked,
        });
    }

    /// Takes one input. Allocates nothing for a tick in steady state beyond the tick's own
    /// shared frame per subject (see [`Ticker::publish`]).
    pub fn handle_input(&mut self, input: Input<'_>) {
        match input {
            Input::Timeout(time) => self.run_due(time),
            Input::Frame {
                subject,
                time,
                capture_nanos,
                seq,
                pose,
            } => self.take_frame(subject, time, capture_nanos, seq, pose),
            Input::Health { subject, state } => self.take_health(subject, state),
            Input::Mapping { target, built } => {
                if !self.ticker.offer_mapping(target, built) {
                    tracing::warn!("a mapping for subject {target}, which no performer drives");
                }
            }
            Input::Command(command) => {
                if let EngineCommand::SkeletonChanged { subject } = command {
                    self.resize_fed(subject);
                }
                self.queue.builds.push_back(command);
            }
        }
    }

    /// A source's state: set on its subject; a change is reported to clients at once (a
    /// loss or a recovery does not wait for the next periodic report).
    fn take_health(&mut self, subject: u32, state: SourceState) {
        let Some(s) = self.ticker.subject(subject) else {
            return;
        };
        if s.health.state() == state {
            return;
        }
        s.health.set_state(state);
        let queue = &mut self.queue;
        self.status.report(self.now, |e| queue.events.push_back(e));
    }

    /// Sizes the check buffer of fed source `subject` for its skeleton now (rare: a live
    /// source learnt a new skeleton).
    fn resize_fed(&mut self, subject: u32) {
        let Some(s) = self.ticker.subject(subject) else {
            return;
        };
        if let Some(fed) = self.fed.iter_mut().find(|f| f.subject == subject) {
            if fed.checked.num_bones() != s.skeleton().num_bones() {
                fed.checked = s.skeleton().rest_pose();
            }
        }
    }

    /// The next output; [`Output::Timeout`] once nothing else waits.
    pub fn poll_output(&mut self) -> Output<'_> {
        let next = self.next_wake_up();
        let q = &mut self.queue;
        if q.datagrams.is_empty() {
            // Every bundle handed out earlier is done with (its borrow ended).
            q.bundles.clear();
        }
        if let Some((to, start, end)) = q.datagrams.pop_front() {
            return Output::Datagram {
                to,
                bundle: &q.bundles[start..end],
            };
        }
        if let Some(frame) = q.frames.pop_front() {
            return Output::Frame(frame);
        }
        if let Some(event) = q.events.pop_front() {
            return Output::Event(event);
        }
        if let Some(command) = q.builds.pop_front() {
            return Output::Build(command);
        }
        if let Some(t) = q.ticked.take() {
            return Output::Ticked(t);
        }
        Output::Timeout(next)
    }

    /// When the engine next wants to run (the time it was last given if something is due
    /// already).
    pub fn next_wake_up(&self) -> Instant {
        let now = self.now;
        if self.performed.is_some() {
            return now;
        }
        let mut at = self.schedule.next(now).min(self.status_every.next(now));
        if !self.footplants.is_empty() {
            at = at.min(self.footplant_every.next(now));
        }
        at
    }

    /// Runs what is due at `time`: the encoding of a performed tick, a new tick's
    /// performers, the checks off the tick.
    fn run_due(&mut self, time: TickTime) {
        let now = time.instant;
        self.now = self.now.max(now);
        if let Some(started) = self.performed.take() {
            // Stamped when encoded (after the performers ran), as `send_nanos` is defined.
            self.ticker
                .publish(started, time.unix_nanos, &mut self.queue);
            self.queue.ticked = Some(started);
        } else if self.schedule.take_due(now) {
            self.ticker.perform(time);
            self.performed = Some(time);
            return;
        }
        let queue = &mut self.queue;
        if !self.footplants.is_empty() && self.footplant_every.take_due(now) {
            self.footplants.sample(|e| queue.events.push_back(e));
        }
        if self.status_every.take_due(now) {
            self.status.look(now, |e| queue.events.push_back(e));
        }
    }

    fn take_frame(
        &mut self,
        subject: u32,
        time: TickTime,
        capture_nanos: u64,
        seq: u64,
        pose: &Pose,
    ) {
        let Some(fed) = self.fed.iter_mut().find(|f| f.subject == subject) else {
            tracing::warn!("a frame for subject {subject}, whose slot the engine does not hold");
            return;
        };
        let Some(s) = self.ticker.subject(subject) else {
            return;
        };
        if pose.num_bones() != fed.checked.num_bones() {
            if pose.num_bones() != s.skeleton().num_bones() {
                tracing::warn!("subject {subject}: a pose of another skeleton, not taken");
                return;
            }
            // The source's skeleton changed before its command came through: sized now.
            fed.checked = pose.clone();
        }
        // Checked as a whole where it enters the engine (the check renormalises rotations,
        // so on a copy).
        fed.checked.copy_from(pose);
        if !s.admit(&mut fed.checked, time.instant) {
            return;
        }
        s.publish_source_pose(&fed.writer, &fed.checked, time, (capture_nanos, seq));
        if fed.wakes {
            self.schedule.wake(time.instant);
        }
    }
}
