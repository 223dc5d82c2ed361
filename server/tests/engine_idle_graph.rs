//! The engine on a simulated clock, with no socket and no real time: a source drives the
//! built-in mannequin through the whole tick ([`Ticker`]), its frames and VMC bundles handed to
//! a recording [`TickOutput`]. The source is lost: on the very tick that sees it the target
//! walks its idle graph (a motion graph of the procedural walk cycle, another rig than the
//! character, retargeted by the server), moving on every tick, its limbs on the graph's poses
//! rather than the performer's, never at rest. The source returns: the target blends back over
//! exactly the resume time (0.3 s of simulated ticks) and its upper body is then the live
//! motion again. No frame of the take-over or the hand-back jumps further than twice the larger
//! of the two motions' own p99 per-tick joint displacement. Six seconds of 60 Hz ticks take a
//! fraction of a second of wall time.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use glam::Quat;
use rigcast_engine::clock::TickTime;
use rigcast_engine::performer::{BuiltMapping, Performer};
use rigcast_engine::settings::OnLost;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::{OutFrame, TickContext, TickOutput, Ticker, VmcTarget};
use rigcast_protocol::{SourceState, TargetMotion};
use rigcast_retarget::graph::play::clips_onto_rig;
use rigcast_retarget::{world_transforms, Clip, Pose, Skeleton};

mod common;

const TARGET: u32 = 1;
/// 60 Hz, in whole nanoseconds.
const TICK: Duration = Duration::from_nanos(16_666_667);
const RESUME: Duration = Duration::from_millis(300);
const LIVE_TICKS: usize = 120;
const LOST_TICKS: usize = 180;
const BACK_TICKS: usize = 120;

/// What the tick handed out during one tick.
#[derive(Default)]
struct Recorded {
    frames: Vec<OutFrame>,
    datagrams: Vec<(SocketAddr, usize)>,
}

impl TickOutput for Recorded {
    fn frame(&mut self, frame: OutFrame) {
        self.frames.push(frame);
    }

    fn datagram(&mut self, to: SocketAddr, bundle: &[u8]) {
        self.datagrams.push((to, bundle.len()));
    }
}

/// One tick as the test saw it.
struct Seen {
    pose: Pose,
    seq: u64,
    motion: TargetMotion,
}

/// The performer's own motion, unlike anything in the graph: the walk cycle's legs and spine
/// with both arms hanging down and swinging a little.
fn live_clip() -> Clip {
    let walk = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
    let sk = walk.skeleton.clone();
    let poses = (walk.poses.iter().enumerate())
        .map(|(i, p)| {
            let mut p = p.clone();
            let swing = 0.2 * (i as f32 / 60.0 * std::f32::consts::TAU).sin();
            let mut set = |name: &str, q: Quat| p.rotations[sk.bone(name).unwrap().index()] = q;
            set("LeftUpperArm", Quat::from_rotation_z(-1.3 + swing));
            set("RightUpperArm", Quat::from_rotation_z(1.3 + swing));
            set("LeftLowerArm", Quat::IDENTITY);
            p
        })
        .collect();
    Clip::new("arms_down", sk, poses, 1.0 / 30.0).unwrap()
}

fn bones_named(skel: &Skeleton, prefixes: &[&str]) -> Vec<usize> {
    (0..skel.num_bones())
        .filter(|&i| prefixes.iter().any(|p| skel.names()[i].starts_with(p)))
        .collect()
}

/// Worst angle (degrees) over `bones` between `pose` and the pose of `clip` that matches best.
fn best_match_degrees(clip: &[Pose], bones: &[usize], pose: &Pose) -> f32 {
    clip.iter()
        .map(|p| {
            (bones.iter())
                .map(|&b| p.rotations[b].angle_between(pose.rotations[b]))
                .fold(0.0f32, f32::max)
        })
        .fold(f32::MAX, f32::min)
        .to_degrees()
}

/// Largest joint displacement from each pose to the next, metres.
fn joint_steps(skel: &Skeleton, poses: &[&Pose]) -> Vec<f32> {
    let worlds: Vec<Vec<glam::Vec3>> = (poses.iter())
        .map(|p| {
            world_transforms(skel, p)
                .iter()
                .map(|w| w.translation)
                .collect()
        })
        .collect();
    (worlds.windows(2))
        .map(|w| {
            (w[0].iter().zip(&w[1]))
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max)
        })
        .collect()
}

fn p99(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[((v.len() - 1) as f32 * 0.99) as usize]
}

#[test]
fn a_lost_source_walks_the_idle_graph_and_hands_back_on_a_simulated_clock() {
    let wall = std::time::Instant::now();
    // The graph: the procedural walk cycle, another rig than the character.
    let (walk, target, idle) = common::walk_idle_graph(TICK.as_secs_f32());
    let blend = Duration::from_secs_f32(idle.blend_secs());
    let live = live_clip();
    let (source, source_tx) = Subject::new(0, "performer".into(), live.skeleton.clone());
    let source = Arc::new(source);
    let (_, mapping) = common::rest_mapping(&live.skeleton, &target);
    let (t, target_tx) = common::target_subject(TARGET, &target);
    let mailbox = Arc::new(std::sync::Mutex::new(Some(BuiltMapping {
        mapping,
        foot_lock: None,
        graft: None,
    })));
    let performer = Performer::new(
        t.clone(),
        target_tx,
        vec![source.clone()],
        mailbox,
        OnLost::Idle,
    )
    .with_idle_graph(idle, Some(RESUME));
    let receiver: SocketAddr = "127.0.0.1:39539".parse().unwrap();
    let mut ticker = Ticker::new(TickContext {
        subjects: Arc::new(vec![source.clone(), t.clone()]),
        vmc: vec![VmcTarget {
            addr: receiver,
            subject_index: TARGET as usize,
        }],
        performers: vec![performer],
    });

    // The simulated clock: every tick exactly 1/60 s after the last; the performer's source
    // sends a frame every other tick (30 fps) while it is live.
    let mut now = TickTime::now();
    let mut sent = 0usize;
    let mut seen: Vec<Seen> = Vec::new();
    let mut run = |ticks: usize, sending: bool, seen: &mut Vec<Seen>| {
        for _ in 0..ticks {
            now = now.after(TICK);
            if sending && seen.len() % 2 == 0 {
                source_tx.send_modify(|f| {
                    f.pose.copy_from(&live.poses[sent % live.poses.len()]);
                    f.seq += 1;
                    f.capture_nanos = now.unix_nanos;
                });
                sent += 1;
            }
            let mut out = Recorded::default();
            ticker.tick(now, &mut out);
            // Every tick hands out both subjects' frames and the target's VMC bundles.
            let subjects: Vec<u32> = out.frames.iter().map(|f| f.subject).collect();
            assert_eq!(subjects, [0, TARGET], "tick {}", seen.len());
            assert!(
                !out.datagrams.is_empty(),
                "no VMC bundle at tick {}",
                seen.len()
            );
            assert!(out
                .datagrams
                .iter()
                .all(|&(to, n)| to == receiver && n <= 1500));
            let frame = t.latest.borrow();
            seen.push(Seen {
                pose: frame.pose.clone(),
                seq: frame.seq,
                motion: t.stats.motion.load(),
            });
        }
    };
    run(LIVE_TICKS, true, &mut seen);
    source.health.set_state(SourceState::Lost);
    run(LOST_TICKS, false, &mut seen);
    source.health.set_state(SourceState::Live);
    run(BACK_TICKS, true, &mut seen);
    let (lost, back) = (LIVE_TICKS, LIVE_TICKS + LOST_TICKS);

    // The labels follow the simulated clock exactly: on the graph from the tick that sees the
    // loss, resuming from the tick that sees the return until the resume time has passed.
    assert!(seen[..lost].iter().all(|s| s.motion == TargetMotion::Live));
    assert!(seen[lost..back]
        .iter()
        .all(|s| s.motion == TargetMotion::IdleGraph));
    let resume_ticks = (RESUME.as_nanos() as f64 / TICK.as_nanos() as f64).ceil() as usize;
    let live_again = (back..seen.len())
        .find(|&i| seen[i].motion == TargetMotion::Live)
        .expect("never live again");
    println!(
        "live again {} ticks after the return (resume {resume_ticks} ticks)",
        live_again - back
    );
    assert!(seen[back..live_again]
        .iter()
        .all(|s| s.motion == TargetMotion::Resuming));
    assert!((resume_ticks - 1..=resume_ticks + 1).contains(&(live_again - back)));
    assert!(seen[live_again..]
        .iter()
        .all(|s| s.motion == TargetMotion::Live));

    // On the graph a new pose goes out every tick.
    for w in seen[lost - 1..back].windows(2) {
        assert_eq!(w[1].seq, w[0].seq + 1, "the walk skipped a tick");
    }
    let skel = &*target;
    let limbs = bones_named(skel, &["upperarm", "lowerarm", "thigh", "calf"]);
    let upper = bones_named(skel, &["spine", "neck", "head", "upperarm", "lowerarm"]);
    let rig = Clip::new(
        "mannequin",
        target.clone(),
        vec![skel.rest_pose()],
        1.0 / 60.0,
    )
    .unwrap();
    let graph_on_target: Vec<Pose> = clips_onto_rig(std::slice::from_ref(&walk), &rig)
        .unwrap()
        .into_iter()
        .flat_map(|c| c.poses)
        .collect();
    // Two seconds of live ticks hold every frame of the performer's one-second cycle.
    let live_on_target: Vec<Pose> = seen[..lost].iter().map(|s| s.pose.clone()).collect();
    let settled = lost + (blend.as_nanos() / TICK.as_nanos()) as usize + 6;
    let on_graph = &seen[settled..back];
    let median = |mut v: Vec<f32>| {
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    let to_graph = median(
        (on_graph.iter())
            .map(|s| best_match_degrees(&graph_on_target, &limbs, &s.pose))
            .collect(),
    );
    let to_live = median(
        (on_graph.iter())
            .map(|s| best_match_degrees(&live_on_target, &upper, &s.pose))
            .collect(),
    );
    let rest = skel.rest_pose();
    let off_rest = (on_graph.iter())
        .map(|s| best_match_degrees(std::slice::from_ref(&rest), &limbs, &s.pose))
        .fold(f32::MAX, f32::min);
    println!(
        "on the graph: limbs {to_graph:.1}° from the graph's poses, upper body {to_live:.1}° from the live motion, limbs at least {off_rest:.1}° off rest"
    );
    assert!(off_rest > 10.0, "the target went to rest");
    assert!(to_live > 5.0, "the target kept the live motion");
    assert!(
        to_graph < to_live / 2.0,
        "the target's limbs are not on the graph"
    );
    for w in on_graph.windows(6) {
        let poses: Vec<&Pose> = w.iter().map(|s| &s.pose).collect();
        assert!(
            joint_steps(skel, &poses).iter().sum::<f32>() > 0.005,
            "frozen on the graph"
        );
    }

    // Once live again the upper body is the live motion: a source pose the target showed
    // before the loss gives the same rotations now (0.1°: the angle between two unit
    // quaternions, an acos near 1 in f32, resolves no finer).
    let back_err = (seen[live_again..].iter())
        .map(|s| best_match_degrees(&live_on_target, &upper, &s.pose))
        .fold(0.0f32, f32::max);
    println!("after the resume: upper body within {back_err:.3}° of the live motion");
    assert!(back_err < 0.1, "not back on the live motion: {back_err}°");

    // Neither hand-over jumps further than twice the larger motion's own p99 per-tick step.
    let steps = |range: std::ops::Range<usize>| {
        let poses: Vec<&Pose> = seen[range].iter().map(|s| &s.pose).collect();
        joint_steps(skel, &poses)
    };
    let (live_p99, graph_p99) = (p99(steps(0..lost)), p99(steps(settled..back)));
    let bound = 2.0 * live_p99.max(graph_p99);
    let worst = |range| steps(range).into_iter().fold(0.0f32, f32::max);
    let take_over = worst(lost - 1..settled);
    let hand_back = worst(back - 1..seen.len());
    println!(
        "joint steps: live p99 {:.1} mm, graph p99 {:.1} mm, bound {:.1} mm; take-over {:.1} mm, hand-back {:.1} mm",
        live_p99 * 1e3,
        graph_p99 * 1e3,
        bound * 1e3,
        take_over * 1e3,
        hand_back * 1e3
    );
    assert!(take_over <= bound, "the take-over jumped {take_over} m");
    assert!(hand_back <= bound, "the hand-back jumped {hand_back} m");
    println!(
        "{} simulated ticks in {:.0} ms of wall time",
        seen.len(),
        wall.elapsed().as_secs_f64() * 1e3
    );
}
