//! Walks that arrive on time ("reach pose X by time T", issue 14): start at frame A and be
//! at frame B exactly `frames` frames later, wandering on the way.
//!
//! ```text
//!  layer r  = for every node, the cheapest walk of exactly r frames to B (∞: none)
//!             layer 0 = { B: 0 };  layer r(n) = min over n's edges e → m of cost(e) + layer r − 1(m)
//!             (cost: the cheapest walk's transition cost; the next frame of a clip costs 0)
//!  quickest = frames of the quickest walk A → B (a breadth-first search back from B: every
//!             edge plays one frame)
//!  walk     = while the time left is past the last layer: wander as the live walker does
//!             (stay in the clip; at a settled node switch with chance ½, ∝ exp(−d / (threshold/2)))
//!             within the last layers: the cheapest step that keeps layer (frames left − 1) finite
//! ```
//!
//! Every step keeps "a walk of exactly the time left to B exists", so the walk cannot miss:
//! it is at B on the asked frame, and when the time left equals the quickest time to B the
//! only steps left are those of a quickest way in. A layer in which every kept node is finite
//! is followed by layers that are too (every kept node has an edge into the kept component),
//! so layers are stored only up to the first such one: the "horizon" (209 frames, 1.7 s, on
//! the four mocap clips of the tests), past which wandering is free. Inside it the walk is the
//! cheapest of its exact length — wandering there would take the transitions the timing
//! forces, often one right after another, mid-blend. When no walk has exactly the asked length
//! (all loops on the way of the wrong lengths; rare on real graphs), the nearest length that
//! has one is walked and the result says so; a time shorter than the quickest walk is an
//! error that says by how much.

use std::collections::VecDeque;

use super::build::MotionGraph;
use super::walk::{
    blend_frames, check_nodes, transition_cost, wander_step, Edges, Rng, WanderRule,
};
use super::GraphError;

/// Most layer values a plan may hold (64 MiB): a graph whose layers never fill up could
/// otherwise make a very long walk take memory in proportion to its length.
const MAX_LAYER_VALUES: usize = 1 << 24;

/// A walk that arrives at its goal on a given frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TimedWalk {
    /// Nodes in play order: the start first, the goal last, one frame apart.
    pub nodes: Vec<usize>,
    /// The arrival frame asked for.
    pub asked_frames: usize,
    /// Frames of the quickest walk from the start to the goal.
    pub quickest_frames: usize,
}

impl TimedWalk {
    /// The frame the walk is at its goal (its last node): `asked_frames` unless no walk of
    /// that length exists.
    pub fn arrival_frame(&self) -> usize {
        self.nodes.len().saturating_sub(1)
    }
}

/// A walk from `from` that is at `to` exactly `frames` frames later (global frames, both
/// kept), wandering (seeded by `seed`) on the way; free switches go only into the clips
/// `stay` marks (indexed by clip; missing entries or an empty slice allow every clip).
pub fn timed_walk(
    graph: &MotionGraph,
    from: usize,
    to: usize,
    frames: usize,
    seed: u64,
    stay: &[bool],
) -> Result<TimedWalk, GraphError> {
    check_nodes(graph, &[from, to])?;
    let edges = Edges::new(graph);
    let quickest = frames_to(graph, &edges, to)[from].ok_or(GraphError::NoWalk { from, to })?;
    if frames < quickest {
        return Err(GraphError::ArrivalTooSoon {
            from,
            to,
            asked_frames: frames,
            quickest_frames: quickest,
            frame_time_secs: graph.frame_time_secs,
        });
    }
    // Room past the asked length to find the nearest one that works, should it not.
    let limit = frames.saturating_add(frames / 4 + 64);
    let layers = Layers::build(graph, &edges, to, limit)?;
    let arrival = nearest_length(&layers, from, frames, quickest);
    let clip_of: Vec<usize> = (0..graph.num_frames())
        .map(|n| graph.locate(n).map_or(0, |(c, _)| c))
        .collect();
    let preferred = |n: usize| stay.get(clip_of[n]).copied().unwrap_or(true);
    let nodes = wander_to(graph, &edges, &layers, (from, arrival), seed, preferred)?;
    Ok(TimedWalk {
        nodes,
        asked_frames: frames,
        quickest_frames: quickest,
    })
}

/// Frames of the quickest walk from every node to `goal` (`None`: cannot reach it): a
/// breadth-first search from `goal` along reversed edges.
pub fn frames_to(graph: &MotionGraph, edges: &Edges, goal: usize) -> Vec<Option<usize>> {
    let n = graph.num_frames();
    let mut into: Vec<Vec<u32>> = vec![Vec::new(); n];
    for node in 0..n {
        if edges.has_successor(node) {
            into[node + 1].push(node as u32);
        }
        for (t, _) in edges.transitions(node) {
            into[t].push(node as u32);
        }
    }
    let mut out = vec![None; n];
    let mut queue = VecDeque::from([goal]);
    out[goal] = Some(0);
    while let Some(v) = queue.pop_front() {
        let d = out[v].unwrap_or(0) + 1;
        for &u in &into[v] {
            let u = u as usize;
            if out[u].is_none() {
                out[u] = Some(d);
                queue.push_back(u);
            }
        }
    }
    out
}

/// For every `r` up to the horizon, the cheapest walk of exactly `r` frames from every node
/// to the goal (infinite: there is none).
struct Layers {
    costs: Vec<Vec<f32>>,
    /// True when the last stored layer is finite on every kept node (so are all later ones).
    full: bool,
    kept: Vec<bool>,
}

impl Layers {
    /// Layers `0 ..= limit`, or fewer when one fills up (or empties: then all later do).
    fn build(
        graph: &MotionGraph,
        edges: &Edges,
        goal: usize,
        limit: usize,
    ) -> Result<Layers, GraphError> {
        let n = graph.num_frames();
        let kept: Vec<bool> = (0..n).map(|i| graph.is_kept(i)).collect();
        let mut first = vec![f32::INFINITY; n];
        first[goal] = 0.0;
        let mut layers = Layers {
            costs: vec![first],
            full: graph.num_kept() == 1,
            kept,
        };
        while layers.costs.len() <= limit && !layers.full {
            if layers.costs.len() * n > MAX_LAYER_VALUES {
                return Err(GraphError::BadSetting(format!(
                    "a walk of {limit} frames is too long to plan on this graph"
                )));
            }
            let next = layers.next_layer(graph, edges);
            let finite = next.iter().filter(|c| c.is_finite()).count();
            layers.full = finite == graph.num_kept();
            layers.costs.push(next);
            if finite == 0 {
                break;
            }
        }
        Ok(layers)
    }

    fn next_layer(&self, graph: &MotionGraph, edges: &Edges) -> Vec<f32> {
        let last = self.costs.last().map_or(&[][..], |l| &l[..]);
        let at = |m: usize| last.get(m).copied().unwrap_or(f32::INFINITY);
        (0..graph.num_frames())
            .map(|node| {
                if !self.kept[node] {
                    return f32::INFINITY;
                }
                let stay = if edges.has_successor(node) {
                    at(node + 1)
                } else {
                    f32::INFINITY
                };
                edges
                    .transitions(node)
                    .map(|(t, d)| transition_cost(&graph.settings, d) + at(t))
                    .fold(stay, f32::min)
            })
            .collect()
    }

    /// The cheapest walk of exactly `r` frames from `node` to the goal, when stored.
    fn cost(&self, r: usize, node: usize) -> Option<f32> {
        self.costs.get(r).and_then(|l| l.get(node)).copied()
    }

    /// True when `node` has a walk of exactly `r` frames to the goal (beyond the stored
    /// layers only a full last one says yes).
    fn holds(&self, r: usize, node: usize) -> bool {
        match self.cost(r, node) {
            Some(c) => c.is_finite(),
            None => self.full && self.kept.get(node).copied().unwrap_or(false),
        }
    }
}

/// The walk length nearest `frames` (not below `quickest`) with a walk of exactly that many
/// frames from `from`; ties go to the later one. `quickest` always has one.
fn nearest_length(layers: &Layers, from: usize, frames: usize, quickest: usize) -> usize {
    (0..=frames - quickest)
        .find_map(|d| {
            [frames + d, frames - d]
                .into_iter()
                .find(|&r| r >= quickest && layers.holds(r, from))
        })
        .unwrap_or(quickest)
}

/// Wanders from `start.0` for `start.1` frames, stepping only where the goal stays reachable
/// in exactly the frames left (so the last node is the goal); inside the stored layers, by
/// their cheapest steps.
fn wander_to(
    graph: &MotionGraph,
    edges: &Edges,
    layers: &Layers,
    (from, frames): (usize, usize),
    seed: u64,
    preferred: impl Fn(usize) -> bool,
) -> Result<Vec<usize>, GraphError> {
    let blend = blend_frames(&graph.settings, graph.frame_time_secs);
    let mut rng = Rng::new(seed);
    let mut nodes = Vec::with_capacity(frames + 1);
    nodes.push(from);
    let (mut here, mut since_switch) = (from, 0);
    for left in (0..frames).rev() {
        let rule = WanderRule {
            possible: |n: usize| layers.holds(left, n),
            preferred: &preferred,
            threshold: graph.settings.threshold,
            settled: since_switch >= blend,
        };
        // Layer `left + 1` held `here`, so one of its edges leads into layer `left`.
        let next = match cheapest_step(graph, edges, layers, here, left) {
            Some(next) => Some(next),
            None => wander_step(edges, here, &rule, &mut rng),
        }
        .ok_or(GraphError::NoWalk { from, to: here })?;
        since_switch = if next == here + 1 {
            since_switch + 1
        } else {
            0
        };
        nodes.push(next);
        here = next;
    }
    Ok(nodes)
}

/// The step from `here` that starts the cheapest walk of exactly `left` more frames to the
/// goal, when layer `left` is stored (`None` past the horizon); the clip's next frame wins
/// ties.
fn cheapest_step(
    graph: &MotionGraph,
    edges: &Edges,
    layers: &Layers,
    here: usize,
    left: usize,
) -> Option<usize> {
    layers.cost(left, here)?;
    let stay = edges.has_successor(here).then(|| {
        (
            here + 1,
            layers.cost(left, here + 1).unwrap_or(f32::INFINITY),
        )
    });
    let jumps = edges.transitions(here).map(|(t, d)| {
        let c = transition_cost(&graph.settings, d) + layers.cost(left, t).unwrap_or(f32::INFINITY);
        (t, c)
    });
    stay.into_iter()
        .chain(jumps)
        .filter(|(_, c)| c.is_finite())
        .fold(None, |best: Option<(usize, f32)>, (n, c)| match best {
            Some((_, bc)) if bc <= c => best,
            _ => Some((n, c)),
        })
        .map(|(n, _)| n)
}
