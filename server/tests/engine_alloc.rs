//! Driven as the host drives it (sources' poses handed over through their doors into the
//! inbox, the inbox drained into the engine, the time in, every output taken), the engine
//! allocates exactly one shared frame buffer per subject per tick, as the tick alone does
//! (`tick_alloc.rs`): the doors' pose buffers, the inbox's drain, its output queue, the copy a
//! fed pose is checked in, its timetable and its status and foot-plant checks (every 50 ms and
//! 30 Hz between the ticks, nothing to report) reuse their memory. The once-a-second `source_status` report allocates (a report
//! for the clients), so the ticks measured fall between two of them. Proven with a counting
//! global allocator, so this file holds only this test.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::Duration;

use rigcast_engine::inbox::Inbox;
use rigcast_engine::performer::BuiltMapping;
use rigcast_engine::settings::OnLost;
use rigcast_engine::tick::VmcTarget;
use rigcast_engine::{Engine, Input, Output, TickTime};

mod common;

#[path = "common/counting.rs"]
mod counting;

/// What one simulated moment handed out: frames, datagrams, events, ticks.
#[derive(Default, Debug, PartialEq)]
struct Counts {
    frames: usize,
    datagrams: usize,
    events: usize,
    ticks: usize,
}

/// Passes `now` as the host does and takes every output without keeping it (keeping would
/// allocate); returns the counts and the next wake-up.
fn run_at(engine: &mut Engine, now: TickTime, counts: &mut Counts) -> std::time::Instant {
    engine.handle_input(Input::Timeout(now));
    loop {
        match engine.poll_output() {
            Output::Datagram { bundle, .. } => {
                assert!(bundle.len() <= 1500);
                counts.datagrams += 1;
            }
            Output::Frame(_) => counts.frames += 1,
            Output::Event(_) => counts.events += 1,
            Output::Ticked(_) => counts.ticks += 1,
            Output::Build(c) => panic!("nothing was asked for, yet {c:?}"),
            Output::Timeout(at) if at <= now.instant => engine.handle_input(Input::Timeout(now)),
            Output::Timeout(at) => return at,
        }
    }
}

#[test]
fn the_engine_allocates_one_buffer_per_subject_per_tick() {
    let clip = rigcast_server::demo::procedural_clip(30, 30.0).unwrap();
    let (mut subjects, writers) = common::source_subjects(3, &clip.skeleton);
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let (_, mapping) = common::rest_mapping(&clip.skeleton, &target);
    let (t, performer) = common::performer(3, &target, &subjects[..1], OnLost::Ease);
    let inbox = Inbox::new(|| {});
    let doors: Vec<_> = (subjects.iter())
        .map(|s| inbox.door(s.clone(), false))
        .collect();
    subjects.push(t.clone());
    let receiver = "127.0.0.1:39539".parse().unwrap();
    let t0 = TickTime::now();
    let vmc = [0, 3].map(|subject_index| VmcTarget {
        addr: receiver,
        subject_index,
    });
    let mut engine = common::engine(subjects, vmc.to_vec(), vec![performer], 60.0, t0.instant);
    for (id, tx) in writers.into_iter().enumerate() {
        engine.feed(id as u32, tx, false);
    }
    inbox.mapping(
        3,
        BuiltMapping {
            mapping,
            foot_lock: None,
            graft: None,
        },
    );

    // Every source sends a new pose before each tick; the host sleeps until the wake-up.
    let mut k = 0usize;
    let mut wake = t0.instant;
    let mut step = |engine: &mut Engine, counts: &mut Counts, wake: &mut std::time::Instant| {
        let now = t0.after(wake.duration_since(t0.instant));
        for (id, door) in doors.iter().enumerate() {
            let pose = &clip.poses[(k + id) % clip.poses.len()];
            assert!(door.hand_over(now, 0, 0, pose));
        }
        inbox.drain(|input| engine.handle_input(input));
        k += 1;
        *wake = run_at(engine, now, counts);
    };
    // Warm up past the second status report (at 1 s): buffers grow to size, the performer
    // takes its mapping, every report slot is filled once.
    let mut warm = Counts::default();
    while wake.duration_since(t0.instant) < Duration::from_millis(1100) {
        step(&mut engine, &mut warm, &mut wake);
    }
    assert!(warm.events >= 2, "no status report while warming up");

    // The next 40 ticks (to about 1.77 s, before the next report at 2 s): frames only.
    let mut counts = Counts::default();
    let before = counting::allocations();
    while counts.ticks < 40 {
        step(&mut engine, &mut counts, &mut wake);
    }
    let allocations = counting::allocations() - before;
    assert!(wake.duration_since(t0.instant) < Duration::from_secs(2));
    assert_eq!(
        counts.events, 0,
        "nothing to report between two status reports"
    );
    assert_eq!((counts.ticks, counts.frames), (40, 40 * 4), "{counts:?}");
    assert!(counts.datagrams >= 80, "{counts:?}");
    assert_eq!(allocations, 40 * 4, "one shared frame per subject per tick");
}
