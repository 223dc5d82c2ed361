//! Building a [`MotionGraph`] from clips: measure, search, connect, prune.

use std::ops::Range;
use std::sync::Arc;

use petgraph::algo::tarjan_scc;
use petgraph::graph::{DiGraph, NodeIndex};
use serde::{Deserialize, Serialize};

use super::body::BodyPoints;
use super::features::{ClipFeatures, ClipTrack};
use super::search::{find_similar, SearchParams, Similar};
use super::GraphError;
use crate::analysis::{analyze, Analysis, SkeletonView};
use crate::clip::Clip;

/// How a graph is built and played. Times in seconds; the search converts them to frames at
/// the graph's frame rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GraphSettings {
    /// Frames closer than this are similar (RMS distance per body point over the window, in
    /// leg lengths).
    pub threshold: f32,
    /// The comparison window (Kovar: about 1/3 s).
    pub window_secs: f32,
    /// Weight of velocities against positions: a velocity counts as the distance it covers
    /// in this time.
    pub velocity_weight_secs: f32,
    /// Grid step of the coarse search.
    pub coarse_step_secs: f32,
    /// Radius of the local-minimum neighbourhood.
    pub minimum_radius_secs: f32,
    /// Cross-fade length at a transition.
    pub blend_secs: f32,
    /// Extra cost of taking a transition in goal-directed walks, as seconds of motion: walks
    /// prefer staying in a clip unless jumping saves more than this.
    pub transition_cost_secs: f32,
}

impl Default for GraphSettings {
    fn default() -> Self {
        GraphSettings {
            threshold: 0.25,
            window_secs: 1.0 / 3.0,
            velocity_weight_secs: 0.1,
            coarse_step_secs: 1.0 / 30.0,
            minimum_radius_secs: 1.0 / 15.0,
            blend_secs: 1.0 / 3.0,
            transition_cost_secs: 0.25,
        }
    }
}

impl GraphSettings {
    fn check(&self) -> Result<(), GraphError> {
        let positive = [
            ("threshold", self.threshold),
            ("window_secs", self.window_secs),
            ("coarse_step_secs", self.coarse_step_secs),
            ("minimum_radius_secs", self.minimum_radius_secs),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(GraphError::BadSetting(format!(
                    "{name} must be > 0, not {v}"
                )));
            }
        }
        let non_negative = [
            ("velocity_weight_secs", self.velocity_weight_secs),
            ("blend_secs", self.blend_secs),
            ("transition_cost_secs", self.transition_cost_secs),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(GraphError::BadSetting(format!(
                    "{name} must be ≥ 0, not {v}"
                )));
            }
        }
        Ok(())
    }

    /// Frames for a duration at `frame_time` (at least `min`).
    pub fn frames(secs: f32, frame_time: f64, min: usize) -> usize {
        ((secs as f64 / frame_time).round() as usize).max(min)
    }
}

/// One clip of a graph: its nodes are `offset .. offset + frames`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraphClip {
    /// Clip name.
    pub name: String,
    /// Where the clip was read from (informational; set by whoever saves the graph).
    #[serde(default)]
    pub path: Option<String>,
    /// [`clip_fingerprint`] of the clip as given (before resampling), hex.
    pub fingerprint: String,
    /// Frames after resampling to the graph's frame time.
    pub frames: usize,
    /// First node.
    pub offset: usize,
}

/// A transition edge: after frame `from`, play frame `to` (global frame indices).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transition {
    /// Node the jump leaves.
    pub from: u32,
    /// Node played next.
    pub to: u32,
    /// Frame distance between `from` and `to − 1`.
    pub distance: f32,
}

/// A motion graph: nodes are the frames of its clips, edges the clips' own successions and
/// the transitions; only the largest strongly connected component is kept.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionGraph {
    /// Settings it was built with.
    pub settings: GraphSettings,
    /// Seconds per node.
    pub frame_time_secs: f64,
    /// Clips, in order.
    pub clips: Vec<GraphClip>,
    /// Transition edges between kept nodes, sorted by `from`.
    pub transitions: Vec<Transition>,
    /// Kept nodes as sorted, disjoint ranges.
    pub kept: Vec<Range<usize>>,
    /// Similar pairs the search found (before pruning).
    pub similar_pairs: usize,
    /// Strongly connected components before pruning.
    pub components: usize,
}

/// FNV-1a over the skeleton fingerprint, frame time and every pose value (quantised to 1e-5,
/// like the skeleton fingerprint): which clip a graph was built from, stable across runs.
pub fn clip_fingerprint(clip: &Clip) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |v: u64| {
        for b in v.to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(clip.skeleton.fingerprint());
    eat(clip.frame_time_secs.to_bits());
    eat(clip.poses.len() as u64);
    let q = |x: f32| (x as f64 * 1e5).round() as i64 as u64;
    for p in &clip.poses {
        for r in &p.rotations {
            r.to_array().into_iter().for_each(|x| eat(q(x)));
        }
        for t in &p.translations {
            t.to_array().into_iter().for_each(|x| eat(q(x)));
        }
    }
    h
}

impl MotionGraph {
    /// Builds a graph from `clips` (resampled to the first clip's frame time), analysing each
    /// clip's rig. `progress` gets the fraction done.
    pub fn build(
        clips: &[Clip],
        settings: GraphSettings,
        progress: &mut dyn FnMut(f32),
    ) -> Result<MotionGraph, GraphError> {
        let analyses: Vec<Analysis> = clips
            .iter()
            .map(|c| analyze(&SkeletonView::from_clip(&c.skeleton, &c.poses)))
            .collect();
        Self::build_analyzed(clips, &analyses, settings, progress)
    }

    /// [`MotionGraph::build`] with the clips' analyses given (e.g. with a file's own humanoid
    /// map applied).
    pub fn build_analyzed(
        clips: &[Clip],
        analyses: &[Analysis],
        settings: GraphSettings,
        progress: &mut dyn FnMut(f32),
    ) -> Result<MotionGraph, GraphError> {
        settings.check()?;
        let first = clips.iter().find(|c| !c.poses.is_empty());
        let frame_time = first.ok_or(GraphError::NoFrames)?.frame_time_secs;
        let half = GraphSettings::frames(settings.window_secs / 2.0, frame_time, 1);
        let mut features = Vec::with_capacity(clips.len());
        let mut graph_clips = Vec::with_capacity(clips.len());
        let mut offset = 0;
        let mut loops = Vec::with_capacity(clips.len());
        for (index, (clip, analysis)) in clips.iter().zip(analyses).enumerate() {
            let clip = resample(clip, frame_time, index)?;
            let body = BodyPoints::find(analysis).map_err(|e| GraphError::ClipMismatch {
                index,
                name: clip.name.clone(),
                reason: e.to_string(),
            })?;
            let track = ClipTrack::measure(&clip.skeleton, &body, &clip.poses);
            let f = ClipFeatures::compute(
                &track,
                half,
                frame_time as f32,
                settings.velocity_weight_secs,
            );
            loops.push(loop_closure(&track, settings.threshold));
            graph_clips.push(GraphClip {
                name: clip.name.clone(),
                path: None,
                fingerprint: format!("{:016x}", clip_fingerprint(&clips[index])),
                frames: clip.num_frames(),
                offset,
            });
            offset += clip.num_frames();
            features.push(f);
        }
        let params = SearchParams {
            stride: GraphSettings::frames(settings.coarse_step_secs, frame_time, 1),
            radius: GraphSettings::frames(settings.minimum_radius_secs, frame_time, 2),
            min_gap: GraphSettings::frames(settings.window_secs, frame_time, 2),
            threshold: settings.threshold,
        };
        let similar = find_similar(&features, params, progress);
        Ok(connect(settings, frame_time, graph_clips, &similar, &loops))
    }

    /// Number of nodes (frames), kept or not.
    pub fn num_frames(&self) -> usize {
        self.clips.last().map(|c| c.offset + c.frames).unwrap_or(0)
    }

    /// Number of kept nodes.
    pub fn num_kept(&self) -> usize {
        self.kept.iter().map(|r| r.len()).sum()
    }

    /// True when `node` is in the kept component.
    pub fn is_kept(&self, node: usize) -> bool {
        let i = self.kept.partition_point(|r| r.end <= node);
        self.kept.get(i).is_some_and(|r| r.contains(&node))
    }

    /// The clip and frame within it of a node.
    pub fn locate(&self, node: usize) -> Option<(usize, usize)> {
        let c = self.clips.partition_point(|c| c.offset + c.frames <= node);
        let clip = self.clips.get(c)?;
        (node >= clip.offset).then(|| (c, node - clip.offset))
    }

    /// Number of kept edges: clip successions between kept nodes plus transitions.
    pub fn num_edges(&self) -> usize {
        let succession = (0..self.num_frames())
            .filter(|&n| self.has_successor(n))
            .count();
        succession + self.transitions.len()
    }

    /// True when `node + 1` is the next frame of the same clip and both are kept.
    pub fn has_successor(&self, node: usize) -> bool {
        self.locate(node)
            .is_some_and(|(c, f)| f + 1 < self.clips[c].frames)
            && self.is_kept(node)
            && self.is_kept(node + 1)
    }
}

fn resample(clip: &Clip, frame_time: f64, index: usize) -> Result<Clip, GraphError> {
    if (clip.frame_time_secs - frame_time).abs() <= 1e-9 {
        return Ok(clip.clone());
    }
    clip.resampled(frame_time)
        .map_err(|e| GraphError::ClipMismatch {
            index,
            name: clip.name.clone(),
            reason: e.to_string(),
        })
}

/// The whole graph from similar pairs: both directions of every pair, then Tarjan's SCCs.
fn connect(
    settings: GraphSettings,
    frame_time: f64,
    clips: Vec<GraphClip>,
    similar: &[Similar],
    loops: &[Option<f32>],
) -> MotionGraph {
    let n = clips.last().map(|c| c.offset + c.frames).unwrap_or(0);
    let mut all = candidate_transitions(&clips, similar, loops);
    let (largest, components) = largest_component(n, &clips, &all);
    let kept = to_ranges(&largest);
    let mut in_kept = vec![false; n];
    largest.iter().for_each(|&i| in_kept[i] = true);
    all.retain(|t| in_kept[t.from as usize] && in_kept[t.to as usize]);
    all.sort_by_key(|t| (t.from, t.to));
    MotionGraph {
        settings,
        frame_time_secs: frame_time,
        clips,
        transitions: all,
        kept,
        similar_pairs: similar.len(),
        components,
    }
}

/// Every transition the similar pairs allow (each pair both ways: from one frame to the
/// frame after the other), and each looping clip's jump from its last frame to its second.
fn candidate_transitions(
    clips: &[GraphClip],
    similar: &[Similar],
    loops: &[Option<f32>],
) -> Vec<Transition> {
    let node = |(c, f): (usize, usize)| clips[c].offset + f;
    let mut all = Vec::with_capacity(similar.len() * 2);
    for s in similar {
        let (a, b) = (node(s.a), node(s.b));
        all.push(Transition {
            from: a as u32,
            to: (b + 1) as u32,
            distance: s.distance,
        });
        all.push(Transition {
            from: b as u32,
            to: (a + 1) as u32,
            distance: s.distance,
        });
    }
    for (c, d) in clips.iter().zip(loops) {
        if let (Some(distance), true) = (d, c.frames > 2) {
            all.push(Transition {
                from: (c.offset + c.frames - 1) as u32,
                to: (c.offset + 1) as u32,
                distance: *distance,
            });
        }
    }
    all
}

/// The largest strongly connected component of the `n` frames (each clip's frames in order,
/// and the transitions), as sorted frame indices, and how many components there are.
fn largest_component(n: usize, clips: &[GraphClip], all: &[Transition]) -> (Vec<usize>, usize) {
    let mut g: DiGraph<(), ()> = DiGraph::with_capacity(n, n + all.len());
    for _ in 0..n {
        g.add_node(());
    }
    for c in clips {
        for f in 1..c.frames {
            g.add_edge(
                NodeIndex::new(c.offset + f - 1),
                NodeIndex::new(c.offset + f),
                (),
            );
        }
    }
    for t in all {
        g.add_edge(
            NodeIndex::new(t.from as usize),
            NodeIndex::new(t.to as usize),
            (),
        );
    }
    let sccs = tarjan_scc(&g);
    let components = sccs.len();
    let mut largest: Vec<usize> = sccs
        .into_iter()
        .max_by_key(|c| c.len())
        .map(|c| c.into_iter().map(|i| i.index()).collect())
        .unwrap_or_default();
    largest.sort_unstable();
    (largest, components)
}

/// A looping clip (game animations usually are: the last frame repeats the first) closes on
/// itself: the distance between its last and first postures (body points in their heading
/// frames, leg lengths, RMS) when under half the threshold. Its windows cannot be compared
/// (they would run past the ends), hence the stricter bound on the posture alone. The loop
/// becomes the transition last → 1 (frame 0 stands for the last).
fn loop_closure(track: &ClipTrack, threshold: f32) -> Option<f32> {
    let (first, last) = (track.points.first()?, track.points.last()?);
    let local = |p: &[glam::Vec3; super::body::NUM_POINTS], h: &super::Planar| {
        let back = h.inverse(track.up);
        p.map(|q| back.apply(track.up, q))
    };
    let a = local(first, track.headings.first()?);
    let b = local(last, track.headings.last()?);
    let sum: f32 = a.iter().zip(&b).map(|(x, y)| x.distance_squared(*y)).sum();
    let d = (sum / a.len() as f32).sqrt() / track.leg;
    (d <= 0.5 * threshold).then_some(d)
}

fn to_ranges(sorted: &[usize]) -> Vec<Range<usize>> {
    let mut out: Vec<Range<usize>> = Vec::new();
    for &i in sorted {
        match out.last_mut() {
            Some(r) if r.end == i => r.end = i + 1,
            _ => out.push(i..i + 1),
        }
    }
    out
}

/// Shared clip storage for playback (clips resampled to the graph's frame time).
pub fn resampled_clips(graph: &MotionGraph, clips: &[Clip]) -> Result<Vec<Arc<Clip>>, GraphError> {
    clips
        .iter()
        .enumerate()
        .map(|(i, c)| resample(c, graph.frame_time_secs, i).map(Arc::new))
        .collect()
}
