//! Walks on a graph: goal-directed (the cheapest walk between two frames, seed 001's start
//! and end pose) and the per-node edge lists a [`super::Walker`] wanders on.

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
    for f in [from, to] {
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
        let cost = step + s.transition_cost_secs * (1.0 + t.distance / s.threshold);
        g.add_edge(
            NodeIndex::new(t.from as usize),
            NodeIndex::new(t.to as usize),
            cost,
        );
    }
    g
}

/// Frames of the blend at a transition.
pub fn blend_frames(settings: &GraphSettings, frame_time: f64) -> usize {
    GraphSettings::frames(settings.blend_secs, frame_time, 1)
}
