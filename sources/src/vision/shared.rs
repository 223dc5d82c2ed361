//! [`SharedVision`]: one camera or video, one pipeline thread, one live source per tracked
//! person.
//!
//! ```text
//!  pipeline thread: FrameSource ─▶ PosePipeline::track_frame (the people tracked: one batch)
//!      │  per slot #k: pose, raw landmarks, seen ──▶ Mutex<Slots> (copied, no allocation)
//!      ├─ the slots seen: publication stamps, Condvar::notify_all
//!      └─ PosePipeline::find_people (the finder, when due) ─▶ every other slot published alike
//!                  │
//!   PersonSource #0 ◀─┤ next_frame: wait for a newer publication of slot #0, copy its pose
//!   PersonSource #1 ◀─┘ next_frame: wait for a newer publication of slot #1, copy its pose
//! ```
//!
//! The finder runs after the tracked people's poses are out: a detector pass (several while
//! someone is missing) costs as much as a landmark run or more, and must not stand between a
//! tracked performer's frame and the wire (`glass_to_pose` is measured to the first
//! publication with someone in it).
//!
//! Each [`PersonSource`] is a [`LiveSource`] of its own, so each person is a subject of its
//! own with its own health: a person who leaves the view makes only their subject report
//! "no person in view" (and, after [`LOST_AFTER`], lost), while the others stay live. The
//! thread starts at the first `next_frame` of any person (like [`super::VisionSource`], a file
//! starts playing when the server starts reading it) and stops when the last person source
//! is dropped. A subject that reads more slowly than the pipeline produces skips to the latest
//! frame (latest pose wins, as everywhere else).

use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rigcast_retarget::{Pose, Skeleton};

use super::camera_modes::CameraMode;
use super::error::VisionError;
use super::frame::{FrameSource, RgbFrame};
use super::landmarks::Landmarks;
use super::pipeline::PosePipeline;
use super::source::LandmarkTap;
use crate::live::{
    unix_nanos_now, wait_until, HealthTracker, LiveSource, NextFrame, Pace, RawTap, SourceError,
    SourceStatus, StageTimes,
};

/// A camera's stages, in the order its pipeline thread records them (`camera.stages` in
/// `/v1/status`).
pub const CAMERA_STAGES: [&str; 6] = [
    "capture",
    "decode",
    "detect",
    "landmarks",
    "solve",
    "glass_to_pose",
];

/// A person not seen for this long is reported lost (their performer falls back); shorter
/// gaps (someone briefly hidden behind another) only show as "no person in view".
pub const LOST_AFTER: Duration = Duration::from_secs(1);

/// How often the paced pipeline thread looks at the stop flag while waiting for a frame's
/// time.
const STOP_POLL: Duration = Duration::from_millis(50);

/// Why the pipeline thread stopped producing frames.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Ended {
    /// The file ended.
    EndOfInput,
    /// Decoding or inference failed; the message is reported once per subject.
    Failed(String),
}

/// One person's latest result, written by the pipeline thread.
#[derive(Debug)]
struct Slot {
    pose: Pose,
    raw: Landmarks,
    seen: bool,
    /// The publication that last wrote this slot; its person source waits for a newer one.
    publication: u64,
}

/// What the pipeline thread and the person sources share (under one mutex).
#[derive(Debug)]
struct Slots {
    /// Publications so far: two per frame, the tracked people's and then everyone else's
    /// (see [`publish`]).
    publications: u64,
    /// The first publication of the frame being published.
    frame_start: u64,
    /// When the last frame was captured (Unix nanoseconds): for a paced file, when it was
    /// due; for a camera, when its processing started.
    capture_nanos: u64,
    /// When the last frame's processing started (latency is measured from here).
    arrived: Instant,
    /// Frame time of the last frame, seconds from the start of the input.
    time_secs: f64,
    slots: Vec<Slot>,
    ended: Option<Ended>,
    /// Counts the times the camera was lost, with why the last time (cleared by a frame).
    lost: (u64, Option<String>),
    /// A camera's mode (as of its last frame) and where its frames' time went.
    camera: Option<CameraMode>,
    /// The landmark model (`lite`, `full`, …).
    model: &'static str,
    stages: StageTimes<{ CAMERA_STAGES.len() }>,
    /// Set when the last person source is dropped.
    stop: bool,
}

#[derive(Debug)]
struct Shared {
    slots: Mutex<Slots>,
    changed: Condvar,
}

impl Shared {
    /// The slots, even if a thread panicked while holding them (the data is plain values
    /// that are always consistent between fields' writes, so carrying on is safe).
    fn lock(&self) -> MutexGuard<'_, Slots> {
        self.slots.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// What the thread runs, until it is started.
struct Runner {
    frames: Box<dyn FrameSource>,
    pipeline: PosePipeline,
    realtime: bool,
}

/// Owned by every person source; the last one dropped stops the thread.
struct Hub {
    shared: Arc<Shared>,
    runner: Mutex<Option<Runner>>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl Drop for Hub {
    fn drop(&mut self) {
        self.shared.lock().stop = true;
        self.shared.changed.notify_all();
        // Not joined: a webcam read may block for a while and a drop must not. The thread
        // notices `stop` after its current frame and exits on its own.
        let _ = self.thread.get_mut().map(|t| t.take());
    }
}

impl Hub {
    /// Starts the pipeline thread if nobody has yet.
    fn start(&self) -> Result<(), VisionError> {
        let runner = match self.runner.lock() {
            Ok(mut r) => r.take(),
            Err(_) => None,
        };
        let Some(runner) = runner else {
            return Ok(());
        };
        let shared = self.shared.clone();
        let handle = std::thread::Builder::new()
            .name("vision".into())
            .spawn(move || run_pipeline(runner, &shared))
            .map_err(|e| VisionError::Thread(e.to_string()))?;
        if let Ok(mut t) = self.thread.lock() {
            *t = Some(handle);
        }
        Ok(())
    }
}

/// One camera or video shared by several subjects (one per tracked person).
pub struct SharedVision {
    hub: Arc<Hub>,
    skeleton: Arc<Skeleton>,
    num_people: usize,
}

debug_fields!(SharedVision { num_people });

impl SharedVision {
    /// Serves `frames` through `pipeline` for [`PosePipeline::num_people`] people. With
    /// `realtime`, frames are released at their timestamps (a file plays like a camera).
    pub fn new(frames: Box<dyn FrameSource>, pipeline: PosePipeline, realtime: bool) -> Self {
        let skeleton = pipeline.skeleton().clone();
        let num_people = pipeline.num_people();
        let slots = (0..num_people)
            .map(|_| Slot {
                pose: skeleton.rest_pose(),
                raw: Landmarks::default(),
                seen: false,
                publication: 0,
            })
            .collect();
        let shared = Arc::new(Shared {
            slots: Mutex::new(Slots {
                publications: 0,
                frame_start: 0,
                capture_nanos: 0,
                arrived: Instant::now(),
                time_secs: 0.0,
                slots,
                ended: None,
                lost: (0, None),
                camera: None,
                model: pipeline.model().as_str(),
                stages: StageTimes::default(),
                stop: false,
            }),
            changed: Condvar::new(),
        });
        let hub = Hub {
            shared,
            runner: Mutex::new(Some(Runner {
                frames,
                pipeline,
                realtime,
            })),
            thread: Mutex::new(None),
        };
        SharedVision {
            hub: Arc::new(hub),
            skeleton,
            num_people,
        }
    }

    /// People tracked (`#0` … `#num_people-1`).
    pub fn num_people(&self) -> usize {
        self.num_people
    }

    /// The BlazePose skeleton every person's poses are on.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// The live source of person `#person`, named `name`.
    pub fn person(
        &self,
        person: usize,
        name: impl Into<String>,
    ) -> Result<PersonSource, VisionError> {
        if person >= self.num_people {
            return Err(VisionError::NoSuchPerson {
                person,
                num_people: self.num_people,
            });
        }
        let mut health = HealthTracker::new(LOST_AFTER);
        health.set_detail("waiting for the first frame");
        Ok(PersonSource {
            name: name.into(),
            hub: self.hub.clone(),
            skeleton: self.skeleton.clone(),
            person,
            last_publication: 0,
            last_lost: 0,
            ended_reported: false,
            health,
            tap: LandmarkTap::new(),
        })
    }
}

/// The pipeline thread: decode, pace, process, publish, until the input ends, fails or the
/// last person source is dropped.
fn run_pipeline(mut runner: Runner, shared: &Shared) {
    let (w, h) = runner.frames.size();
    let mut frame = RgbFrame::new(w, h);
    let mut started = Pace::default();
    let mut anchor_nanos: Option<u64> = None;
    let ended = loop {
        if shared.lock().stop {
            return;
        }
        match runner.frames.next_frame(&mut frame) {
            Ok(true) => {}
            Ok(false) => break Ended::EndOfInput,
            Err(VisionError::CameraLost(why)) => {
                // Not the end: the camera is looked for again at the next read.
                let mut s = shared.lock();
                s.lost = (s.lost.0 + 1, Some(why));
                drop(s);
                shared.changed.notify_all();
                continue;
            }
            Err(e) => break Ended::Failed(e.to_string()),
        }
        if runner.realtime && !pace(&frame, &mut started, shared) {
            return;
        }
        let arrived = Instant::now();
        let capture_nanos = capture_time(runner.realtime, &frame, &mut anchor_nanos);
        let found_before = runner.pipeline.stats().find_nanos;
        // The people already tracked go out first: the finder (a detector pass, several
        // while someone is missing) runs after their poses are published, so it never holds
        // up this frame's poses. Whoever it finds goes out as soon as it is done.
        if let Err(e) = runner.pipeline.track_frame(&frame) {
            break Ended::Failed(e.to_string());
        }
        let stamp = Stamp {
            arrived,
            capture_nanos,
            time_secs: frame.time_secs,
        };
        let mut posed = publish(&runner.pipeline, &stamp, shared, true).then(unix_nanos_now);
        if let Err(e) = runner.pipeline.find_people(&frame) {
            break Ended::Failed(e.to_string());
        }
        if publish(&runner.pipeline, &stamp, shared, false) {
            posed.get_or_insert_with(unix_nanos_now);
        }
        if frame.clock.captured_unix_nanos > 0 {
            record_stages(&runner, shared, (&frame, arrived), found_before, posed);
        }
    };
    shared.lock().ended = Some(ended);
    shared.changed.notify_all();
}

/// When `frame` was captured, in Unix nanoseconds. A paced file's frame is "captured" when it
/// is due, wall clock anchored at the first frame (`anchor_nanos`): consumers can tell the
/// frame's place in the file from it, and a pipeline that falls behind shows as latency
/// instead of being hidden. A camera's frame was captured when its driver says.
fn capture_time(realtime: bool, frame: &RgbFrame, anchor_nanos: &mut Option<u64>) -> u64 {
    if realtime {
        let frame_nanos = (frame.time_secs.max(0.0) * 1e9).round() as u64;
        let anchor =
            *anchor_nanos.get_or_insert_with(|| unix_nanos_now().saturating_sub(frame_nanos));
        anchor + frame_nanos
    } else if frame.clock.captured_unix_nanos > 0 {
        frame.clock.captured_unix_nanos
    } else {
        unix_nanos_now()
    }
}

/// A camera frame's time in each stage (queue, decode, detect, model, solve, to its pose out),
/// for the status; `arrived` when the pipeline took it, `found_before` the finder's time
/// before it, `posed` when its first pose went out.
fn record_stages(
    runner: &Runner,
    shared: &Shared,
    (frame, arrived): (&RgbFrame, Instant),
    found_before: u64,
    posed: Option<u64>,
) {
    let detect = runner.pipeline.stats().find_nanos - found_before;
    let model = arrived
        .elapsed()
        .saturating_sub(runner.pipeline.solve_time());
    let c = frame.clock;
    let times = [
        c.dequeued_unix_nanos.saturating_sub(c.captured_unix_nanos),
        c.decoded_unix_nanos.saturating_sub(c.dequeued_unix_nanos),
        detect,
        (model.as_nanos() as u64).saturating_sub(detect),
        runner.pipeline.solve_time().as_nanos() as u64,
        posed
            .unwrap_or_else(unix_nanos_now)
            .saturating_sub(c.captured_unix_nanos),
    ];
    let mut s = shared.lock();
    s.camera = runner.frames.camera_mode();
    s.stages.record(times);
}

/// Sleeps until `frame` is due (wall clock from the first frame); false when stopped while
/// waiting.
fn pace(frame: &RgbFrame, pace: &mut Pace, shared: &Shared) -> bool {
    let due = pace.due(frame.time_secs, Instant::now());
    while !wait_until(due, Instant::now() + STOP_POLL) {
        if shared.lock().stop {
            return false;
        }
    }
    true
}

/// When a frame was captured and its processing started, and its time in the input.
struct Stamp {
    arrived: Instant,
    capture_nanos: u64,
    time_secs: f64,
}

/// Copies slots' results out of the pipeline and wakes the person sources, each slot once
/// per frame: `tracked` publishes the people the tracker followed (before the finder runs),
/// then the rest publishes every other slot, seen by the finder or not (so nobody is reported
/// out of view before the finder had its look). Returns whether anyone published was seen.
fn publish(pipeline: &PosePipeline, stamp: &Stamp, shared: &Shared, tracked: bool) -> bool {
    let mut s = shared.lock();
    let publication = s.publications + 1;
    let this_frame = if tracked { publication } else { s.frame_start };
    let (mut written, mut anyone) = (false, false);
    for (k, slot) in s.slots.iter_mut().enumerate() {
        let seen = pipeline.person(k).is_some();
        if (tracked && !seen) || slot.publication >= this_frame {
            continue;
        }
        slot.seen = seen;
        slot.publication = publication;
        (written, anyone) = (true, anyone || seen);
        if let (true, Some(pose)) = (seen, pipeline.pose(k)) {
            slot.pose.copy_from(pose);
        }
        if let Some(raw) = pipeline.raw_person(k) {
            slot.raw = *raw;
        }
    }
    s.publications = publication;
    if tracked {
        s.frame_start = publication;
    }
    if !written {
        return false;
    }
    s.lost.1 = None;
    s.capture_nanos = stamp.capture_nanos;
    s.arrived = stamp.arrived;
    s.time_secs = stamp.time_secs;
    drop(s);
    shared.changed.notify_all();
    anyone
}

/// One tracked person of a [`SharedVision`], as a live source on the BlazePose skeleton.
pub struct PersonSource {
    name: String,
    hub: Arc<Hub>,
    skeleton: Arc<Skeleton>,
    person: usize,
    /// The publication of this person's slot this source last read.
    last_publication: u64,
    /// The pipeline's camera-lost counter when this source last reported a loss.
    last_lost: u64,
    ended_reported: bool,
    health: HealthTracker,
    tap: LandmarkTap,
}

debug_fields!(PersonSource { name, person });

/// What one read of the shared slots found.
enum Read {
    /// A newer frame; the person seen in it (their pose copied out) or not.
    Frame {
        seen: bool,
        arrived: Instant,
        capture_nanos: u64,
    },
    /// Nothing newer within the timeout.
    Nothing,
    /// The camera went away (reported once per loss); the pipeline keeps looking for it.
    Lost(String),
    /// The input is over (reported once).
    Ended(Ended),
}

impl PersonSource {
    /// Which person this is (`#person`).
    pub fn person(&self) -> usize {
        self.person
    }

    /// Waits up to `timeout` for a frame newer than the last one read and copies this
    /// person's pose into `out`. No allocation once `out` fits the skeleton.
    fn read(&mut self, timeout: Duration, out: &mut Pose) -> Read {
        let shared = &self.hub.shared;
        let deadline = Instant::now() + timeout;
        let mut s = shared.lock();
        loop {
            if s.slots[self.person].publication > self.last_publication {
                break;
            }
            if s.lost.0 > self.last_lost {
                self.last_lost = s.lost.0;
                if let Some(why) = &s.lost.1 {
                    return Read::Lost(why.clone());
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            match &s.ended {
                Some(ended) if !self.ended_reported => return Read::Ended(ended.clone()),
                // Nothing will come any more; still block for the timeout so that the
                // caller's polling loop does not spin.
                Some(_) => {
                    drop(s);
                    std::thread::sleep(left);
                    return Read::Nothing;
                }
                None if left.is_zero() => return Read::Nothing,
                None => {}
            }
            s = match shared.changed.wait_timeout(s, left) {
                Ok((guard, _)) => guard,
                Err(e) => e.into_inner().0,
            };
        }
        let slot = &s.slots[self.person];
        self.last_publication = slot.publication;
        let seen = slot.seen;
        if seen {
            crate::live::fit_pose(out, &self.skeleton);
            out.copy_from(&slot.pose);
        }
        self.tap
            .record_frame(seen.then_some(&slot.raw), s.time_secs, s.capture_nanos);
        Read::Frame {
            seen,
            arrived: s.arrived,
            capture_nanos: s.capture_nanos,
        }
    }
}

impl LiveSource for PersonSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn skeleton(&self) -> Option<Arc<Skeleton>> {
        Some(self.skeleton.clone())
    }

    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame {
        if let Err(e) = self.hub.start() {
            self.health.on_device_lost(e.to_string());
            return Err(SourceError::Stream(std::io::Error::other(e)));
        }
        match self.read(timeout, out) {
            Read::Frame {
                seen: true,
                arrived,
                capture_nanos,
            } => {
                self.health.on_input(Instant::now());
                self.health.set_detail("");
                // The skeleton is fixed (BlazePose), so only the first frame announces it.
                Ok(Some(self.health.produced(arrived, capture_nanos, false)))
            }
            Read::Frame { seen: false, .. } => {
                // Frames keep coming but without this person: after LOST_AFTER the subject
                // is lost (its performer falls back); the other people are unaffected.
                self.health.poll(Instant::now());
                self.health.set_detail("no person in view");
                Ok(None)
            }
            Read::Nothing => {
                self.health.poll(Instant::now());
                Ok(None)
            }
            Read::Lost(why) => {
                self.health.on_device_lost(why);
                Ok(None)
            }
            Read::Ended(ended) => {
                self.ended_reported = true;
                match ended {
                    Ended::EndOfInput => {
                        self.health.on_device_lost("end of input");
                        Ok(None)
                    }
                    Ended::Failed(message) => {
                        self.health.on_device_lost(message.clone());
                        Err(SourceError::Stream(std::io::Error::other(message)))
                    }
                }
            }
        }
    }

    fn status(&self) -> SourceStatus {
        let mut status = self.health.status();
        let s = self.hub.shared.lock();
        status.camera = s.camera.map(|m| rigcast_protocol::control::CameraStatus {
            width: m.width,
            height: m.height,
            fps: m.fps,
            format: m.format.fourcc().to_string(),
            model: s.model.to_string(),
            stages: s.stages.report(&CAMERA_STAGES),
        });
        status
    }

    fn set_raw_tap(&mut self, tap: Option<Box<dyn RawTap>>) {
        self.tap.set(tap);
    }
}
