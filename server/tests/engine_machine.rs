//! The engine as a state machine on a simulated clock, with no socket, no thread and no real
//! time, driven the way the server's host loop drives it: the test passes each input
//! ([`Input::Frame`], [`Input::Health`], [`Input::Mapping`]) at its time, and otherwise
//! sleeps (advances the simulated clock) until the wake-up the engine asked for
//! ([`Output::Timeout`]), keeping everything it yields.
//!
//! - Loss → idle graph → resume: a source at 30 fps between the 60 Hz ticks drives the
//!   built-in mannequin; the ticks keep their own timetable exactly (1/60 s apart however the
//!   inputs fall), each hands out both subjects' frames and VMC bundles, and the target's
//!   motion as the engine's `source_status` events report it goes live → idle graph (within
//!   one status poll and a tick of the loss) → resuming → live (the resume time after the
//!   return), with a report at least once a second and the source reported lost meanwhile.
//! - A camera's pose brings the tick forward: each pose is encoded by a tick at the very time
//!   it is handed over (its handoff wait is zero), two poses closer than the minimum gap get
//!   ticks that far apart, and once poses stop the ticks go on at the period from the last
//!   one.
#![allow(clippy::unwrap_used)]

mod common;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_engine::events::Event;
use rigcast_engine::performer::BuiltMapping;
use rigcast_engine::schedule::MIN_TICK_GAP;
use rigcast_engine::settings::OnLost;
use rigcast_engine::status::MOTION_POLL;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::VmcTarget;
use rigcast_engine::{Input, TickTime};
use rigcast_protocol::{SourceState, TargetMotion};

const TARGET: u32 = 1;
const RATE_HZ: f64 = 60.0;
const RESUME: Duration = Duration::from_millis(300);

/// The time `at` after `t0` on both clocks.
fn at(t0: TickTime, after: Duration) -> TickTime {
    t0.after(after)
}

/// What the test saw over a run.
#[derive(Default)]
struct Run {
    /// Tick start times.
    ticks: Vec<Instant>,
    /// Every `source_status` event: its time, the target's motion, the source's state.
    statuses: Vec<(Instant, TargetMotion, SourceState)>,
}

#[test]
fn loss_idle_and_resume_on_the_engines_own_timetable() {
    let wall = Instant::now();
    let (walk, target, idle) = common::walk_idle_graph((1.0 / RATE_HZ) as f32);
    let (source, source_tx) = Subject::new(0, "performer".into(), walk.skeleton.clone());
    let source = Arc::new(source);
    let (_, mapping) = common::rest_mapping(&walk.skeleton, &target);
    let (t, performer) =
        common::performer(TARGET, &target, std::slice::from_ref(&source), OnLost::Idle);
    let performer = performer.with_idle_graph(idle, Some(RESUME));
    let receiver: SocketAddr = "127.0.0.1:39539".parse().unwrap();
    let t0 = TickTime::now();
    let vmc = vec![VmcTarget {
        addr: receiver,
        subject_index: TARGET as usize,
    }];
    let mut engine = common::engine(
        vec![source.clone(), t.clone()],
        vmc,
        vec![performer],
        RATE_HZ,
        t0.instant,
    );
    engine.feed(0, source_tx, false);
    engine.handle_input(Input::Mapping {
        target: TARGET,
        built: BuiltMapping {
            mapping,
            foot_lock: None,
            graft: None,
        },
    });

    // The source sends at 30 fps, 5 ms after the tick timetable's phase, while it is live;
    // it is lost at 2.005 s and returns at 5.005 s; the run ends at 7 s.
    let frame_every = Duration::from_nanos(1_000_000_000 / 30);
    let (lost_at, back_at, end) = (
        Duration::from_millis(2005),
        Duration::from_millis(5005),
        Duration::from_secs(7),
    );
    let mut run = Run::default();
    let mut next_frame = Duration::from_millis(5);
    let mut health_changes = vec![(back_at, SourceState::Live), (lost_at, SourceState::Lost)];
    let mut wake = t0.instant;
    let mut sent = 0usize;
    loop {
        let live = |d: Duration| d < lost_at || d >= back_at;
        while !live(next_frame) {
            next_frame += frame_every;
        }
        let change = health_changes.last().map(|c| c.0);
        let wake_in = wake.duration_since(t0.instant);
        let next_input = change.map_or(next_frame, |c| c.min(next_frame));
        if next_input < wake_in {
            // An input comes before the engine's wake-up: passed at its time.
            let now = at(t0, next_input);
            if change == Some(next_input) {
                let (_, state) = health_changes.pop().unwrap();
                engine.handle_input(Input::Health { subject: 0, state });
            } else {
                let pose = &walk.poses[sent % walk.poses.len()];
                sent += 1;
                engine.handle_input(Input::Frame {
                    subject: 0,
                    time: now,
                    capture_nanos: 0,
                    seq: 0,
                    pose,
                });
                next_frame += frame_every;
            }
            continue;
        }
        if wake_in > end {
            break;
        }
        let now = at(t0, wake_in);
        let (out, next) = common::engine_at(&mut engine, now);
        assert!(next > now.instant, "asked to run again at the same time");
        wake = next;
        for tick in &out.ticked {
            run.ticks.push(tick.instant);
        }
        // The first tick after the source's first frame (at 5 ms) on: both subjects stream.
        if !out.ticked.is_empty() && wake_in > Duration::from_millis(5) {
            let ids: Vec<u32> = out.frames.iter().map(|f| f.subject).collect();
            assert_eq!(ids, [0, TARGET], "both subjects' frames at {wake_in:?}");
            assert!(!out.datagrams.is_empty(), "no VMC bundle at {wake_in:?}");
            assert!(out
                .datagrams
                .iter()
                .all(|&(to, n)| to == receiver && n <= 1500));
        } else if out.ticked.is_empty() {
            assert!(out.frames.is_empty(), "frames without a tick");
        }
        for event in out.events {
            if let Event::SourceStatus(report) = event {
                let motion = report.targets[0].motion;
                run.statuses
                    .push((now.instant, motion, report.sources[0].state));
            }
        }
    }

    // The ticks keep their timetable exactly: 1/60 s apart from the first, whatever the
    // inputs between them.
    let period = Duration::from_secs_f64(1.0 / RATE_HZ);
    assert_eq!(run.ticks[0], t0.instant);
    for w in run.ticks.windows(2) {
        assert_eq!(w[1] - w[0], period);
    }
    let expected = (end.as_secs_f64() * RATE_HZ) as usize;
    assert!(
        run.ticks.len().abs_diff(expected) <= 1,
        "{} ticks",
        run.ticks.len()
    );

    // source_status at least once a second (and on every change of motion).
    let mut last = t0.instant;
    for &(time, ..) in &run.statuses {
        assert!(
            time - last <= Duration::from_secs(1) + period,
            "a gap before {time:?}"
        );
        last = time;
    }
    // The reported motions, in order, and when each first shows.
    let mut shown: Vec<(TargetMotion, Duration)> = Vec::new();
    for &(time, motion, _) in &run.statuses {
        if shown.last().is_none_or(|s| s.0 != motion) {
            shown.push((motion, time - t0.instant));
        }
    }
    println!("motions as reported: {shown:?}");
    let order: Vec<TargetMotion> = shown.iter().map(|s| s.0).collect();
    assert_eq!(
        order,
        [
            TargetMotion::Live,
            TargetMotion::IdleGraph,
            TargetMotion::Resuming,
            TargetMotion::Live
        ]
    );
    let within = MOTION_POLL + 2 * period;
    let after = |d: Duration, from: Duration| d >= from && d - from <= within;
    assert!(
        after(shown[1].1, lost_at),
        "idle graph reported at {:?}",
        shown[1].1
    );
    assert!(
        after(shown[2].1, back_at),
        "resuming reported at {:?}",
        shown[2].1
    );
    assert!(
        after(shown[3].1, back_at + RESUME),
        "live again reported at {:?}",
        shown[3].1
    );
    // The source is reported lost exactly while it is.
    for &(time, _, state) in &run.statuses {
        let d = time - t0.instant;
        let lost = d >= lost_at && d < back_at;
        assert_eq!(
            state == SourceState::Lost,
            lost,
            "source {state:?} at {d:?}"
        );
    }
    println!(
        "{} ticks, {} status reports, {sent} source frames in {:.0} ms of wall time",
        run.ticks.len(),
        run.statuses.len(),
        wall.elapsed().as_secs_f64() * 1e3
    );
}

#[test]
fn a_cameras_pose_brings_the_tick_forward() {
    let walk = rigcast_server::demo::procedural_clip(30, 30.0).unwrap();
    let (camera, camera_tx) = Subject::new(0, "camera".into(), walk.skeleton.clone());
    let camera = Arc::new(camera);
    let t0 = TickTime::now();
    let rate_hz = 30.0;
    let period = Duration::from_secs_f64(1.0 / rate_hz);
    let mut engine = common::engine(
        vec![camera.clone()],
        Vec::new(),
        Vec::new(),
        rate_hz,
        t0.instant,
    );
    engine.feed(0, camera_tx, true);
    let (first, mut wake) = common::engine_at(&mut engine, t0);
    assert_eq!(first.ticked.len(), 1, "the first tick at the start");

    // Poses every 20 ms (faster than the 33 ms period), then a pose 1 ms after another, then
    // none: ticks follow the poses, the close one waits out the minimum gap, then the period
    // takes over from the last tick.
    let mut poses: Vec<Duration> = (0..10).map(|k| Duration::from_millis(7 + 20 * k)).collect();
    let last_pose = *poses.last().unwrap();
    poses.push(last_pose + Duration::from_millis(1));
    let end = Duration::from_millis(400);
    let mut ticks: Vec<(Duration, Option<u64>)> = Vec::new();
    let mut pending = poses.iter().rev().copied().collect::<Vec<_>>();
    loop {
        let wake_in = wake.duration_since(t0.instant);
        if let Some(&p) = pending.last() {
            if p < wake_in {
                pending.pop();
                let now = at(t0, p);
                let pose = &walk.poses[ticks.len() % walk.poses.len()];
                engine.handle_input(Input::Frame {
                    subject: 0,
                    time: now,
                    capture_nanos: now.unix_nanos,
                    seq: 0,
                    pose,
                });
                wake = engine.next_wake_up();
                continue;
            }
        }
        if wake_in > end {
            break;
        }
        let (out, next) = common::engine_at(&mut engine, at(t0, wake_in));
        for tick in &out.ticked {
            let capture = out.frames.first().map(|f| f.capture_nanos);
            ticks.push((tick.instant - t0.instant, capture));
        }
        wake = next;
    }
    println!("ticks: {:?}", ticks.iter().map(|t| t.0).collect::<Vec<_>>());
    // Each of the first ten poses: a tick at its very time, encoding it.
    for &p in &poses[..10] {
        let tick = ticks.iter().find(|t| t.0 == p);
        let capture = at(t0, p).unix_nanos;
        assert_eq!(tick.map(|t| t.1), Some(Some(capture)), "pose at {p:?}");
    }
    // The pose 1 ms after the last one: its tick the minimum gap after that one.
    let close = last_pose + MIN_TICK_GAP;
    assert!(ticks.iter().any(|t| t.0 == close), "no tick at {close:?}");
    // Between two poses 20 ms apart there is no periodic tick (the period restarts at each).
    let during: Vec<_> = (ticks.iter())
        .filter(|t| t.0 > poses[0] && t.0 < last_pose)
        .collect();
    assert_eq!(during.len(), 8, "{during:?}");
    // Then the period, from the last tick.
    let after: Vec<Duration> = ticks.iter().map(|t| t.0).filter(|&t| t >= close).collect();
    assert!(after.len() >= 3, "{after:?}");
    for w in after.windows(2) {
        assert_eq!(w[1] - w[0], period);
    }
    // The handoff wait of every pose a tick took at once is zero.
    let wire = camera.stats.wire.lock().unwrap().report();
    let handoff = wire.iter().find(|s| s.stage == "handoff").unwrap();
    assert!(handoff.samples >= 10, "{} handoff samples", handoff.samples);
    assert!(handoff.p50_ms == 0.0, "handoff p50 {} ms", handoff.p50_ms);
}
