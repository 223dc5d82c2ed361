//! Walks on a graph: goal-directed (the cheapest walk between two frames, seed 001's start
//! and end pose), the per-node edge lists a [`super::Walker`] wanders on, and the wandering
//! rule itself ([`wander_step`]), shared by the live walker and the timed walks of
//! [`super::timed`].

use petgraph::algo::astar;
use petgraph::graph::{DiGraph, NodeIndex};

use super::build::{GraphSettings, MotionGraph};
use super::GraphError;

/// Outgoing edges of every node, flat (compressed rows) so a live walker reads them without
/// allocating. Only kept nodes have edges.
#[derive(Debug, Clone)]
pub struct Edges {
    start: Vec<u32>,
    to: Vec<u32>,
    distance: Vec<f32>,
    successor: Vec<bool>,
}

impl Edges {
    /// The edge lists of `graph`.
    pub fn new(graph: &MotionGraph) -> Edges {
        let n = graph.num_frames();
        let mut start = Vec::with_capacity(n + 1);
        let mut to = Vec::with_capacity(graph.transitions.len());
        let mut distance = Vec::with_capacity(graph.transitions.len());
        let mut k = 0;
        for node in 0..n {
            start.push(to.len() as u32);
            while let Some(t) = graph.transitions.get(k).filter(|t| t.from as usize == node) {
                to.push(t.to);
                distance.push(t.distance);
                k += 1;
            }
        }
        start.push(to.len() as u32);
        let successor = (0..n).map(|i| graph.has_successor(i)).collect();
        Edges {
            start,
            to,
            distance,
            successor,
        }
    }

    /// Transitions leaving `node`: (target, distance).
    pub fn transitions(&self, node: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        let (a, b) = match (self.start.get(node), self.start.get(node + 1)) {
            (Some(&a), Some(&b)) => (a as usize, b as usize),
            _ => (0, 0),
        };
        self.to[a..b]
            .iter()
            .zip(&self.distance[a..b])
            .map(|(&t, &d)| (t as usize, d))
    }

    /// Number of transitions leaving `node`.
    pub fn num_transitions(&self, node: usize) -> usize {
        match (self.start.get(node), self.start.get(node + 1)) {
            (Some(&a), Some(&b)) => (b - a) as usize,
            _ => 0,
        }
    }

    /// True when `node + 1` follows `node` in the kept graph.
    pub fn has_successor(&self, node: usize) -> bool {
        self.successor.get(node).copied().unwrap_or(false)
    }
}

/// The cheapest walk from `from` to `to` (global frames, both kept): frames played, each
/// costing its time, plus each transition's [`GraphSettings::transition_cost_secs`] scaled
/// up by how far its distance is towards the threshold. The walk lists every node in play
/// order, `from` first and `to` last.
pub fn shortest_walk(
    graph: &MotionGraph,
    from: usize,
    to: usize,
) -> Result<Vec<usize>, GraphError> {
    check_nodes(graph, &[from, to])?;
    let g = petgraph_of(graph);
    // A* without a heuristic is Dijkstra; petgraph's `dijkstra` gives costs, not paths.
    let (_, path) = astar(
        &g,
        NodeIndex::new(from),
        |n| n.index() == to,
        |e| *e.weight(),
        |_| 0.0,
    )
    .ok_or(GraphError::NoWalk { from, to })?;
    Ok(path.into_iter().map(|n| n.index()).collect())
}

/// Refuses frames that are not kept nodes of `graph`.
pub fn check_nodes(graph: &MotionGraph, frames: &[usize]) -> Result<(), GraphError> {
    for &f in frames {
        if f >= graph.num_frames() {
            return Err(GraphError::NotANode {
                frame: f,
                reason: "past the last frame",
            });
        }
        if !graph.is_kept(f) {
            return Err(GraphError::NotANode {
                frame: f,
                reason: "pruned: outside the largest connected component",
            });
        }
    }
    Ok(())
}

/// The kept graph as a petgraph digraph weighted by the walk costs of [`shortest_walk`].
pub fn petgraph_of(graph: &MotionGraph) -> DiGraph<(), f32> {
    let n = graph.num_frames();
    let s = &graph.settings;
    let step = graph.frame_time_secs as f32;
    let mut g = DiGraph::with_capacity(n, n + graph.transitions.len());
    for _ in 0..n {
        g.add_node(());
    }
    for i in 0..n {
        if graph.has_successor(i) {
            g.add_edge(NodeIndex::new(i), NodeIndex::new(i + 1), step);
        }
    }
    for t in &graph.transitions {
        let cost = step + transition_cost(s, t.distance);
        g.add_edge(
            NodeIndex::new(t.from as usize),
            NodeIndex::new(t.to as usize),
            cost,
        );
    }
    g
}

/// What taking a transition of `distance` costs a goal-directed walk on top of its frame's
/// time: [`GraphSettings::transition_cost_secs`] scaled up by how far the distance is
/// towards the threshold.
pub fn transition_cost(settings: &GraphSettings, distance: f32) -> f32 {
    settings.transition_cost_secs * (1.0 + distance / settings.threshold)
}

/// Frames of the blend at a transition.
pub fn blend_frames(settings: &GraphSettings, frame_time: f64) -> usize {
    GraphSettings::frames(settings.blend_secs, frame_time, 1)
}

/// Chance of taking a transition at a node that offers one, when wandering.
pub const SWITCH_CHANCE: f32 = 0.5;

/// The wandering's random numbers: xorshift64*, seeded, so that a walk can be reproduced.
#[derive(Debug, Clone, Copy)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed` (0 is taken as 1: xorshift never leaves 0).
    pub fn new(seed: u64) -> Rng {
        Rng(seed.max(1))
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (x >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// What one wandering step may do: `possible` says which nodes a step may land on at all
/// (everything for the live walker; for a timed walk, the nodes from which the goal can still
/// be reached on time), `preferred` which ones a free choice takes (transitions into the
/// clips to stay in).
pub struct WanderRule<P, Q> {
    /// Nodes a step may land on.
    pub possible: P,
    /// Nodes a free switch goes to.
    pub preferred: Q,
    /// The graph's threshold (scales the weights).
    pub threshold: f32,
    /// True when the last switch has settled (its blend is over): only then is a switch
    /// taken by choice.
    pub settled: bool,
}

/// One step of wandering from `here`: stay in the clip, except that at a settled node with a
/// transition the walk switches with chance [`SWITCH_CHANCE`], to a preferred node at random
/// weighted towards the closest (∝ exp(−d / (threshold / 2))); when the clip has no possible
/// next frame, any possible transition. `None` when nothing is possible. Allocates nothing.
pub fn wander_step<P, Q>(
    edges: &Edges,
    here: usize,
    rule: &WanderRule<P, Q>,
    rng: &mut Rng,
) -> Option<usize>
where
    P: Fn(usize) -> bool,
    Q: Fn(usize) -> bool,
{
    let successor = edges.has_successor(here) && (rule.possible)(here + 1);
    let roll = rng.uniform() < SWITCH_CHANCE;
    if successor && !(rule.settled && roll) {
        return Some(here + 1);
    }
    let free = |to: usize| (rule.possible)(to) && (rule.preferred)(to);
    if let Some(to) = pick_transition(edges, here, rule.threshold, rng, free) {
        return Some(to);
    }
    if successor {
        return Some(here + 1);
    }
    // A dead end of the preferred clips: any way on.
    pick_transition(edges, here, rule.threshold, rng, &rule.possible)
}

/// A transition out of `here` at random among those into nodes `ok` accepts, weighted
/// towards the closest; draws from `rng` only when there is one.
fn pick_transition(
    edges: &Edges,
    here: usize,
    threshold: f32,
    rng: &mut Rng,
    ok: impl Fn(usize) -> bool,
) -> Option<usize> {
    let scale = 0.5 * threshold.max(1e-6);
    let weight = |d: f32| (-d / scale).exp();
    let options = || edges.transitions(here).filter(|&(t, _)| ok(t));
    let total: f32 = options().map(|(_, d)| weight(d)).sum();
    if total <= 0.0 {
        return None;
    }
    let mut r = rng.uniform() * total;
    let mut last = None;
    for (t, d) in options() {
        last = Some(t);
        r -= weight(d);
        if r <= 0.0 {
            return Some(t);
        }
    }
    last
}
