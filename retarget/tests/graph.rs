//! Motion graphs on a generated humanoid whose motion has a known period: transitions must
//! join frames a whole number of periods apart, walks must reach their goal with joins under
//! the threshold and a continuous root path, and files must round-trip and refuse damage.

#[path = "common/positions.rs"]
mod positions;
mod retarget_fixtures;

use std::f32::consts::TAU;
use std::sync::Arc;

use glam::{Quat, Vec3};
use retarget_fixtures::Humanoid;
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::graph::walk::shortest_walk;
use rigcast_retarget::graph::{
    timed_walk, GraphError, GraphSettings, MotionGraph, Planar, Playback, Walker,
};
use rigcast_retarget::{Clip, Pose, Skeleton};

const FPS: f32 = 60.0;
/// Period of the generated gait, frames.
const PERIOD: usize = 50;

/// A gait with period `PERIOD`: every bone swings about its own axis with its own phase, the
/// hips travel forward. The swing's size drifts slowly (period 7.3 gaits) so that frames one
/// period apart are close but not equal: distances have isolated minima, as in real capture.
fn gait(skel: &Skeleton, frames: usize, phase: f32) -> Vec<Pose> {
    let rest = skel.rest_pose();
    (0..frames)
        .map(|f| {
            let t = f as f32 / PERIOD as f32 + phase;
            let size = 0.5 + 0.08 * (TAU * t / 7.3).sin();
            let mut p = rest.clone();
            for b in skel.bone_ids().skip(1) {
                let k = b.0 as f32;
                let axis = Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), 0.4).normalize_or_zero();
                let swing = Quat::from_axis_angle(axis, size * (TAU * t + k * 0.9).sin());
                p.rotations[b.index()] = rest.rotations[b.index()] * swing;
            }
            p.translations[0] += Vec3::Z * (1.2 * f as f32 / FPS);
            p
        })
        .collect()
}

fn rig() -> Arc<Skeleton> {
    Arc::new(Humanoid::default().build())
}

fn clip(skel: &Arc<Skeleton>, name: &str, frames: usize, phase: f32) -> Clip {
    Clip::new(
        name,
        skel.clone(),
        gait(skel, frames, phase),
        1.0 / FPS as f64,
    )
    .expect("clip")
}

fn graph(clips: &[Clip]) -> MotionGraph {
    MotionGraph::build(clips, GraphSettings::default(), &mut |_| {}).expect("builds")
}

/// Clip `a` (400 frames) and clip `b` (300 frames, its phase 0.37 periods on) on `skel`, and
/// their graph.
fn two_clips(skel: &Arc<Skeleton>) -> ([Clip; 2], MotionGraph) {
    let clips = [clip(skel, "a", 400, 0.0), clip(skel, "b", 300, 0.37)];
    let g = graph(&clips);
    (clips, g)
}

/// The frame vectors of `clip` as the graph computes them (its body points, windowed).
fn features_of(clip: &Clip) -> rigcast_retarget::graph::features::ClipFeatures {
    use rigcast_retarget::graph::features::{ClipFeatures, ClipTrack};
    let a = analyze(&SkeletonView::from_clip(&clip.skeleton, &clip.poses));
    let body = rigcast_retarget::graph::BodyPoints::find(&a).expect("body");
    let track = ClipTrack::measure(&clip.skeleton, &body, &clip.poses);
    let s = GraphSettings::default();
    let half = GraphSettings::frames(s.window_secs / 2.0, clip.frame_time_secs, 1);
    ClipFeatures::compute(
        &track,
        half,
        clip.frame_time_secs as f32,
        s.velocity_weight_secs,
    )
}

/// A frame looks the same whichever way its file points: the gait on a copy of the rig turned
/// Z-up (its root turned 90° about X, so it faces −Y) gives the original's frame vectors,
/// written along the body's own axes, so the two join as the same motion.
#[test]
fn a_turned_rig_gives_the_same_frame_vectors() {
    let skel = rig();
    let walk = clip(&skel, "a", 120, 0.0);
    let turn = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let mut raw = skel.to_raw();
    raw.bones[0].rest.rotation = turn * raw.bones[0].rest.rotation;
    raw.bones[0].rest.translation = turn * raw.bones[0].rest.translation;
    let turned_skel = Arc::new(Skeleton::build(&raw).expect("skeleton"));
    let poses = walk
        .poses
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p.rotations[0] = turn * p.rotations[0];
            p.translations[0] = turn * p.translations[0];
            p
        })
        .collect();
    let turned = Clip::new("z-up", turned_skel, poses, walk.frame_time_secs).expect("clip");
    let up = analyze(&SkeletonView::from_clip(&turned.skeleton, &turned.poses)).up;
    assert!(up.abs_diff_eq(Vec3::Z, 1e-4), "{up}");
    let (a, b) = (features_of(&walk), features_of(&turned));
    let mut worst = 0.0f32;
    for i in a.valid_range() {
        let (x, y) = (a.get(i).expect("frame"), b.get(i).expect("frame"));
        worst = worst.max(rigcast_retarget::graph::features::frame_distance(x, y));
    }
    assert!(worst < 1e-4, "{worst} leg lengths apart");
}

#[test]
fn transitions_join_frames_whole_periods_apart() {
    let skel = rig();
    let (_, g) = two_clips(&skel);
    assert!(
        !g.transitions.is_empty(),
        "a periodic motion has transitions"
    );
    let b_start = g.clips[1].offset as f32;
    for t in &g.transitions {
        // Gait phase of each frame, in periods.
        let phase = |n: u32| {
            let n = n as f32;
            if n < b_start {
                n / PERIOD as f32
            } else {
                (n - b_start) / PERIOD as f32 + 0.37
            }
        };
        let gap = phase(t.to - 1) - phase(t.from);
        let off = (gap - gap.round()).abs() * PERIOD as f32;
        assert!(off <= 3.0, "{t:?}: {off} frames off a whole period");
        assert!(t.distance <= g.settings.threshold);
    }
    // Both clips loop into each other: nearly everything stays.
    assert!(
        g.num_kept() as f32 >= 0.9 * g.num_frames() as f32,
        "{}",
        g.num_kept()
    );
    let crossing = g
        .transitions
        .iter()
        .filter(|t| ((t.from as f32) < b_start) != ((t.to as f32) < b_start))
        .count();
    assert!(crossing > 0, "clips a and b are joined");
}

#[test]
fn shortest_walk_reaches_the_goal_through_cheap_joins() {
    let skel = rig();
    let (_, g) = two_clips(&skel);
    let (from, to) = (g.clips[0].offset + 40, g.clips[1].offset + 250);
    let path = shortest_walk(&g, from, to).expect("a walk");
    assert_eq!((path[0], *path.last().expect("nodes")), (from, to));
    for w in path.windows(2) {
        if w[1] != w[0] + 1 {
            let t = g
                .transitions
                .iter()
                .find(|t| t.from as usize == w[0] && t.to as usize == w[1])
                .expect("every jump is a transition");
            assert!(t.distance <= g.settings.threshold);
        } else {
            assert!(g.has_successor(w[0]));
        }
    }
    assert!(matches!(
        shortest_walk(&g, 0, to),
        Err(GraphError::NotANode { frame: 0, .. })
    ));
    assert!(shortest_walk(&g, from, 1_000_000).is_err());
}

/// Largest per-frame move of the root, and of any joint, over `poses`.
fn largest_steps(skel: &Skeleton, poses: &[Pose]) -> (f32, f32) {
    let worlds = positions::joint_positions(skel, poses);
    let mut root: f32 = 0.0;
    let mut joint: f32 = 0.0;
    for w in worlds.windows(2) {
        root = root.max(w[0][0].distance(w[1][0]));
        for (a, b) in w[0].iter().zip(&w[1]) {
            joint = joint.max(a.distance(*b));
        }
    }
    (root, joint)
}

#[test]
fn wandering_keeps_root_and_joints_continuous() {
    let skel = rig();
    let (clips, g) = two_clips(&skel);
    let analysis = analyze(&SkeletonView::from_clip(&skel, &clips[0].poses));
    let pb = Playback::new(&g, &clips, &analysis).expect("playback");
    let mut walker = Walker::new(&g, &pb, 7);
    let mut out = skel.rest_pose();
    let poses: Vec<Pose> = (0..1200)
        .map(|_| {
            walker.step(&pb, &mut out);
            out.clone()
        })
        .collect();
    assert!(
        walker.transitions_taken >= 5,
        "{}",
        walker.transitions_taken
    );
    let (clip_root, clip_joint) = largest_steps(&skel, &clips[0].poses);
    let (root, joint) = largest_steps(&skel, &poses);
    // Transitions add at most 1 cm to the root's largest step, and joints move at most twice
    // as far in a frame as they ever do in the clip.
    assert!(
        root <= clip_root + 0.01,
        "root step {root} vs clip {clip_root}"
    );
    assert!(
        joint <= 2.0 * clip_joint,
        "joint step {joint} vs clip {clip_joint}"
    );
}

#[test]
fn take_over_starts_at_the_nearest_frame_where_the_pose_stands() {
    let skel = rig();
    let clips = [clip(&skel, "a", 400, 0.0)];
    let g = graph(&clips);
    let analysis = analyze(&SkeletonView::from_clip(&skel, &clips[0].poses));
    let pb = Playback::new(&g, &clips, &analysis).expect("playback");
    let mut walker = Walker::new(&g, &pb, 1);
    // Frame 123 turned 90° and moved 5 m: the walker starts at 123 (or one period away) and
    // shows it turned and moved.
    let moved = Planar {
        yaw: 1.57,
        offset: Vec3::new(5.0, 0.0, 0.0),
    };
    let mut pose = skel.rest_pose();
    pb.sample(123, &moved, &mut pose);
    let mut worlds = vec![rigcast_retarget::WorldTransform::IDENTITY; skel.num_bones()];
    let node = walker.take_over(&pb, &pose, 1, &mut worlds);
    let off = (node as i64 - 123).rem_euclid(PERIOD as i64);
    assert!(off <= 1 || off >= PERIOD as i64 - 1, "node {node}");
    let mut shown = skel.rest_pose();
    walker.write(&pb, &mut shown);
    assert!(shown.translations[0].distance(pose.translations[0]) < 0.05);
}

#[test]
fn files_round_trip_and_damage_is_an_error() {
    let skel = rig();
    let g = graph(&[clip(&skel, "a", 300, 0.0)]);
    let text = g.to_json();
    assert_eq!(MotionGraph::from_json(&text).expect("reads"), g);
    let newer = text.replacen("\"version\":1", "\"version\":9", 1);
    let e = MotionGraph::from_json(&newer).expect_err("version 9");
    assert!(e.to_string().contains("version 9"), "{e}");
    assert!(MotionGraph::from_json(&text[..text.len() / 2]).is_err());
    assert!(MotionGraph::from_json("{\"format\":\"x\",\"version\":1}").is_err());
    let far = text.replacen("\"transitions\":[[", "\"transitions\":[[4000000,", 1);
    assert!(MotionGraph::from_json(&far).is_err());
}

#[test]
fn a_rig_without_legs_is_a_clear_error() {
    let mut raw = rigcast_retarget::RawSkeleton::default();
    let root = raw.add("root", None, rigcast_retarget::Transform::IDENTITY);
    raw.add(
        "tip",
        Some(root),
        rigcast_retarget::Transform::from_translation(Vec3::Y),
    );
    let skel = Arc::new(Skeleton::build(&raw).expect("skeleton"));
    let poses = vec![skel.rest_pose(); 30];
    let c = Clip::new("stick", skel, poses, 1.0 / 30.0).expect("clip");
    let e = MotionGraph::build(&[c], GraphSettings::default(), &mut |_| {}).expect_err("no legs");
    assert!(e.to_string().contains("rig has no"), "{e}");
    let e = MotionGraph::build(&[], GraphSettings::default(), &mut |_| {}).expect_err("empty");
    assert!(matches!(e, GraphError::NoFrames));
}

/// Which walk lengths up to `max` lead from `from` to `to`, by a forward search over
/// (node, frames) — independent of the library's backward layers.
fn exact_lengths(g: &MotionGraph, from: usize, to: usize, max: usize) -> Vec<bool> {
    let n = g.num_frames();
    let mut at = vec![false; n];
    at[from] = true;
    let mut out = vec![from == to];
    for _ in 0..max {
        let mut next = vec![false; n];
        for u in (0..n).filter(|&u| at[u]) {
            if g.has_successor(u) {
                next[u + 1] = true;
            }
        }
        for t in g.transitions.iter().filter(|t| at[t.from as usize]) {
            next[t.to as usize] = true;
        }
        at = next;
        out.push(at[to]);
    }
    out
}

#[test]
fn timed_walks_arrive_on_the_nearest_possible_frame_or_say_how_much_too_soon() {
    let skel = rig();
    let (_, g) = two_clips(&skel);
    let (from, to) = (g.clips[0].offset + 40, g.clips[1].offset + 250);
    let cheapest = shortest_walk(&g, from, to).expect("a walk").len() - 1;
    let possible = exact_lengths(&g, from, to, cheapest + 800);
    let quickest = possible.iter().position(|&p| p).expect("reachable");
    let mut exact = 0;
    for (k, frames) in [cheapest, cheapest + 7, cheapest + 100, cheapest + 333]
        .into_iter()
        .enumerate()
    {
        let w = timed_walk(&g, from, to, frames, k as u64 + 1, &[]).expect("a timed walk");
        assert_eq!(w.quickest_frames, quickest);
        let arrival = w.arrival_frame();
        assert!(
            possible[arrival],
            "{arrival} frames is a length a walk can have"
        );
        let off = arrival.abs_diff(frames);
        // No length closer to the asked one has a walk.
        let nearer = frames.saturating_sub(off) + 1..frames + off;
        for (len, _) in possible
            .iter()
            .enumerate()
            .filter(|(l, &p)| p && nearer.contains(l))
        {
            assert!(len < quickest, "{len} frames is nearer {frames}");
        }
        exact += usize::from(off == 0);
        assert_eq!((w.nodes[0], w.nodes[arrival]), (from, to));
        for s in w.nodes.windows(2) {
            let jump = g
                .transitions
                .iter()
                .any(|t| (t.from as usize, t.to as usize) == (s[0], s[1]));
            assert!(jump || (s[1] == s[0] + 1 && g.has_successor(s[0])), "{s:?}");
        }
    }
    assert!(exact >= 1, "the cheapest walk's own length is exact");
    match timed_walk(&g, from, to, quickest - 1, 1, &[]) {
        Err(GraphError::ArrivalTooSoon {
            asked_frames,
            quickest_frames,
            ..
        }) => assert_eq!((asked_frames, quickest_frames), (quickest - 1, quickest)),
        other => panic!("one frame too soon: {other:?}"),
    }
    assert!(matches!(
        timed_walk(&g, 0, to, 100, 1, &[]),
        Err(GraphError::NotANode { frame: 0, .. })
    ));
    assert!(timed_walk(&g, from, usize::MAX, 100, 1, &[]).is_err());
}
