//! What the server's threads hand the engine goes through its inbox and reaches it as
//! `Input`s, tested on a simulated clock with no socket and no thread: the host's loop is the
//! test, which drains the inbox into the engine (as `tick_task::run_engine` does) and passes
//! the time.
//!
//! - Poses: a source's door keeps its newest pose; the tick encodes that one, with the
//!   source's own sequence number and its hand-over time; a pose replaced before the engine
//!   took it still counts in the source's input rate; a pose with a non-finite value is
//!   refused at the door and never replaces a good one; a camera's pose wakes the host's loop
//!   and brings the tick forward to when it was handed over.
//! - Health: a source's state reaches the subject and clients (`source_status`) at the drain,
//!   not at the next status poll; a state handed over twice is one input.
//! - Mappings: a mapping built by the mapper reaches the performer through the inbox; the
//!   target streams nothing before it and, at the next tick, the source's pose retargeted
//!   with it (checked against the same mapping applied offline).
//! - Commands: a client's request leaves the engine for the mapper (`Output::Build`); at most
//!   `COMMANDS_IN_FLIGHT` are on their way, then requests are refused as busy until the
//!   mapper takes one; a source's skeleton change is never refused, and the engine takes the
//!   poses on the new skeleton.
#![allow(clippy::unwrap_used)]

mod common;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use rigcast_engine::events::Event;
use rigcast_engine::inbox::{Busy, Inbox, SourceDoor, COMMANDS_IN_FLIGHT};
use rigcast_engine::performer::BuiltMapping;
use rigcast_engine::settings::OnLost;
use rigcast_engine::status::MOTION_POLL;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::EngineCommand;
use rigcast_engine::{Engine, Input, TickTime};
use rigcast_protocol::frame::decode_frame;
use rigcast_protocol::SourceState;
use rigcast_retarget::{Clip, Pose};

const RATE_HZ: f64 = 60.0;
const MS: Duration = Duration::from_millis(1);

/// The procedural walk (no data files needed).
fn walk() -> Clip {
    rigcast_server::demo::procedural_clip(30, 30.0).unwrap()
}

/// Drains `inbox` into `engine` as the host's loop does; how many inputs of each kind came
/// out: (frames, health, mappings, commands).
fn drain(inbox: &Inbox, engine: &mut Engine) -> [usize; 4] {
    let mut n = [0; 4];
    inbox.drain(|input| {
        n[match &input {
            Input::Frame { .. } => 0,
            Input::Health { .. } => 1,
            Input::Mapping { .. } => 2,
            Input::Command(_) => 3,
            other => panic!("the inbox gave {other:?}"),
        }] += 1;
        engine.handle_input(input);
    });
    n
}

/// Source 0 on `clip`'s skeleton, its door to an inbox, and an engine fed its slot, started
/// now.
fn one_source(clip: &Clip) -> (Arc<Subject>, Inbox, SourceDoor, Engine, TickTime) {
    let (subjects, writers) = common::source_subjects(1, &clip.skeleton);
    let source = subjects[0].clone();
    let inbox = Inbox::new(|| {});
    let door = inbox.door(source.clone(), false);
    let t0 = TickTime::now();
    let mut engine = common::engine(subjects, Vec::new(), Vec::new(), RATE_HZ, t0.instant);
    engine.feed(0, writers.into_iter().next().unwrap(), false);
    (source, inbox, door, engine, t0)
}

/// A frame's rotations as the engine encoded them (version 2).
fn rotations(frame: &rigcast_engine::tick::OutFrame) -> Vec<glam::Quat> {
    decode_frame(&frame.version(2)).unwrap().rotations
}

fn close(a: &[glam::Quat], b: &[glam::Quat]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.dot(*y).abs() > 1.0 - 1e-5)
}

#[test]
fn poses_come_in_through_a_door_newest_first_and_checked() {
    let clip = walk();
    let (subjects, writers) = common::source_subjects(2, &clip.skeleton);
    let woken = Arc::new(AtomicUsize::new(0));
    let inbox = Inbox::new({
        let woken = woken.clone();
        move || {
            woken.fetch_add(1, Ordering::Relaxed);
        }
    });
    let (vmc, camera) = (subjects[0].clone(), subjects[1].clone());
    let vmc_door = inbox.door(vmc.clone(), false);
    let camera_door = inbox.door(camera.clone(), true);
    let t0 = TickTime::now();
    let mut engine = common::engine(subjects, Vec::new(), Vec::new(), RATE_HZ, t0.instant);
    for (id, (tx, wakes)) in writers.into_iter().zip([false, true]).enumerate() {
        engine.feed(id as u32, tx, wakes);
    }
    let (first, _) = common::engine_at(&mut engine, t0);
    assert_eq!(first.ticked.len(), 1);

    // Two poses before the next tick, then one with a non-finite value.
    let (a, b) = (&clip.poses[3], &clip.poses[9]);
    assert!(vmc_door.hand_over(t0.after(2 * MS), 10, 0, a));
    assert!(vmc_door.hand_over(t0.after(4 * MS), 11, 0, b));
    let mut bad = clip.poses[5].clone();
    bad.translations[0].x = f32::NAN;
    assert!(!vmc_door.hand_over(t0.after(5 * MS), 12, 0, &bad));
    assert_eq!(vmc.stats.rejected_poses.load(Ordering::Relaxed), 1);
    assert_eq!(
        woken.load(Ordering::Relaxed),
        0,
        "a VMC pose waits for the tick"
    );
    assert_eq!(
        drain(&inbox, &mut engine),
        [1, 0, 0, 0],
        "the newest pose only"
    );
    assert_eq!(drain(&inbox, &mut engine), [0, 0, 0, 0], "taken once");
    let (out, _) = common::engine_at(&mut engine, t0.after(Duration::from_nanos(16_666_667)));
    assert_eq!(out.ticked.len(), 1);
    let frame = out.frames.iter().find(|f| f.subject == 0).unwrap();
    let decoded = decode_frame(&frame.version(2)).unwrap();
    assert!(
        close(&decoded.rotations, &b.rotations),
        "the tick encodes the newest pose"
    );
    assert_eq!(decoded.header.seq, 11, "the source's own number");
    assert_eq!(
        frame.capture_nanos,
        t0.after(4 * MS).unix_nanos,
        "captured when handed over"
    );
    assert_eq!(
        vmc.stats.input.total(),
        2,
        "the replaced pose still counts as produced"
    );
    // A source that numbers nothing: the next number after the last.
    assert!(vmc_door.hand_over(t0.after(20 * MS), 0, 0, a));
    drain(&inbox, &mut engine);
    assert_eq!(vmc.latest.borrow().seq, 12);

    // A camera's pose wakes the host's loop and brings the tick forward to its hand-over.
    let handed = t0.after(25 * MS);
    assert!(camera_door.hand_over(handed, 0, 0, a));
    assert_eq!(woken.load(Ordering::Relaxed), 1);
    assert!(
        engine.next_wake_up() > handed.instant,
        "no tick due before the pose"
    );
    assert_eq!(drain(&inbox, &mut engine), [1, 0, 0, 0]);
    assert_eq!(
        engine.next_wake_up(),
        handed.instant,
        "a tick at the hand-over"
    );
    let (out, _) = common::engine_at(&mut engine, handed);
    assert_eq!(out.ticked, [handed]);
    let frame = out.frames.iter().find(|f| f.subject == 1).unwrap();
    assert!(close(&rotations(frame), &a.rotations));
    assert_eq!(camera.stats.input.total(), 1);
}

#[test]
fn a_sources_health_reaches_clients_at_the_drain() {
    let clip = walk();
    let (source, inbox, door, mut engine, t0) = one_source(&clip);
    let (first, _) = common::engine_at(&mut engine, t0);
    assert_eq!(first.events.len(), 1, "the first status report");

    // Lost 10 ms in: reported then, not at the next status poll (50 ms).
    let at = t0.after(10 * MS);
    assert!(10 * MS < MOTION_POLL);
    door.health(SourceState::Lost);
    door.health(SourceState::Lost);
    assert_eq!(
        drain(&inbox, &mut engine),
        [0, 1, 0, 0],
        "one change, one input"
    );
    assert_eq!(source.health.state(), SourceState::Lost);
    let (out, _) = common::engine_at(&mut engine, at);
    let states: Vec<SourceState> = (out.events.iter())
        .filter_map(|e| match e {
            Event::SourceStatus(r) => Some(r.sources[0].state),
            _ => None,
        })
        .collect();
    assert_eq!(states, [SourceState::Lost]);
    // Back: the same at once.
    door.health(SourceState::Live);
    drain(&inbox, &mut engine);
    let (out, _) = common::engine_at(&mut engine, t0.after(12 * MS));
    assert!(matches!(&out.events[..], [Event::SourceStatus(r)]
        if r.sources[0].state == SourceState::Live));
}

#[test]
fn a_built_mapping_reaches_the_performer_through_the_inbox() {
    let clip = walk();
    let (subjects, writers) = common::source_subjects(1, &clip.skeleton);
    let source = subjects[0].clone();
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let (t, performer) = common::performer(1, &target, &subjects, OnLost::Ease);
    let inbox = Inbox::new(|| {});
    let door = inbox.door(source.clone(), false);
    let t0 = TickTime::now();
    let all = vec![source.clone(), t.clone()];
    let mut engine = common::engine(all, Vec::new(), vec![performer], RATE_HZ, t0.instant);
    engine.feed(0, writers.into_iter().next().unwrap(), false);
    let pose = &clip.poses[7];
    assert!(door.hand_over(t0, 0, 0, pose));
    drain(&inbox, &mut engine);
    let (out, _) = common::engine_at(&mut engine, t0);
    assert!(
        out.ticked.len() == 1 && out.frames.iter().all(|f| f.subject != 1),
        "no mapping yet: no target frame"
    );
    let rest = target.rest_pose();

    let (_, mapping) = common::rest_mapping(&clip.skeleton, &target);
    let (_, mut offline) = common::rest_mapping(&clip.skeleton, &target);
    let built = BuiltMapping {
        mapping,
        foot_lock: None,
        graft: None,
    };
    inbox.mapping(1, built);
    assert_eq!(drain(&inbox, &mut engine), [0, 0, 1, 0]);
    let (out, _) = common::engine_at(&mut engine, t0.after(Duration::from_nanos(16_666_667)));
    let mut expected: Pose = offline.new_target_pose();
    offline.apply_one(pose, &mut expected).unwrap();
    let mapped = rotations(out.frames.iter().find(|f| f.subject == 1).unwrap());
    assert!(
        !close(&expected.rotations, &rest.rotations),
        "the pose is not the rest"
    );
    assert!(
        close(&mapped, &expected.rotations),
        "the source's pose, retargeted"
    );
}

#[test]
fn commands_leave_for_the_mapper_and_are_bounded() {
    let clip = walk();
    let (source, inbox, door, mut engine, t0) = one_source(&clip);
    let set_performer = || EngineCommand::SetPerformer {
        subject: 1,
        foot_lock: Some(false),
    };

    inbox.request(set_performer()).unwrap();
    assert_eq!(drain(&inbox, &mut engine), [0, 0, 0, 1]);
    let (out, _) = common::engine_at(&mut engine, t0);
    assert!(matches!(
        &out.builds[..],
        [EngineCommand::SetPerformer {
            subject: 1,
            foot_lock: Some(false)
        }]
    ));
    // The mapper has not taken it: 63 more fit, then requests are refused.
    for _ in 1..COMMANDS_IN_FLIGHT {
        inbox.request(set_performer()).unwrap();
    }
    assert_eq!(inbox.request(set_performer()), Err(Busy));
    inbox.command_taken();
    inbox.request(set_performer()).unwrap();
    assert_eq!(inbox.request(set_performer()), Err(Busy));
    drain(&inbox, &mut engine);
    let (out, _) = common::engine_at(&mut engine, t0.after(MS));
    assert_eq!(
        out.builds.len(),
        COMMANDS_IN_FLIGHT,
        "every request passed on, in order"
    );

    // A source's skeleton changes: never refused, and its poses on the new skeleton taken.
    let other = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    assert!(source.set_skeleton(other.clone()));
    inbox.notice(EngineCommand::SkeletonChanged { subject: 0 });
    let mut pose = other.rest_pose();
    pose.rotations[1] = glam::Quat::from_rotation_x(0.5);
    assert!(door.hand_over(t0.after(2 * MS), 0, 0, &pose));
    assert_eq!(drain(&inbox, &mut engine), [1, 0, 0, 1]);
    let (out, _) = common::engine_at(&mut engine, t0.after(2 * MS));
    assert!(matches!(
        &out.builds[..],
        [EngineCommand::SkeletonChanged { subject: 0 }]
    ));
    let latest = source.latest.borrow();
    assert_eq!(latest.pose.num_bones(), other.num_bones());
    assert!(latest.pose.rotations[1].dot(pose.rotations[1]).abs() > 1.0 - 1e-6);
}
