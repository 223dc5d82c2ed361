//! Playing a graph: [`Playback`] holds the frames (one rig) and their headings; a [`Walker`]
//! moves along edges one frame per step and writes the pose, aligning the root at every
//! transition (the new clip's heading put onto the old one's, so the path continues) and
//! cross-fading from the old clip's continuation over the blend time (Kovar:
//! α = 2t³ − 3t² + 1, slerped rotations). A step allocates nothing: the live fallback calls
//! it from the engine tick.

use std::sync::Arc;

use glam::Vec3;

use super::body::{BodyPoints, Planar, NUM_POINTS};
use super::build::{resampled_clips, MotionGraph};
use super::features::ClipTrack;
use super::walk::{blend_frames, wander_step, Edges, Rng, WanderRule};
use super::GraphError;
use crate::analysis::{Analysis, SkeletonView};
use crate::clip::Clip;
use crate::fk::WorldTransform;
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// The frames of a graph on one rig, ready to play.
#[derive(Debug, Clone)]
pub struct Playback {
    skeleton: Arc<Skeleton>,
    body: BodyPoints,
    roots: Vec<BoneId>,
    frames: Vec<Pose>,
    headings: Vec<Planar>,
    /// One past the last frame of each node's clip.
    clip_end: Vec<u32>,
    clip_of: Vec<u16>,
    /// Body points relative to the hips, in the frame's heading frame (nearest-node search).
    postures: Vec<[Vec3; NUM_POINTS]>,
    edges: Edges,
    kept: Vec<bool>,
    blend: usize,
    frame_time: f64,
}

impl Playback {
    /// Prepares `clips` (the graph's clips, in order, all on `analysis`'s rig; they are
    /// resampled to the graph's frame time) for playing `graph`.
    pub fn new(
        graph: &MotionGraph,
        clips: &[Clip],
        analysis: &Analysis,
    ) -> Result<Playback, GraphError> {
        if clips.len() != graph.clips.len() {
            return Err(GraphError::BadSetting(format!(
                "the graph has {} clips, {} were given",
                graph.clips.len(),
                clips.len()
            )));
        }
        let clips = resampled_clips(graph, clips)?;
        let skeleton = clips.first().ok_or(GraphError::NoFrames)?.skeleton.clone();
        let body = BodyPoints::find(analysis)?;
        let mut pb = Playback {
            roots: skeleton.roots().collect(),
            skeleton: skeleton.clone(),
            body,
            frames: Vec::with_capacity(graph.num_frames()),
            headings: Vec::with_capacity(graph.num_frames()),
            clip_end: Vec::with_capacity(graph.num_frames()),
            clip_of: Vec::with_capacity(graph.num_frames()),
            postures: Vec::with_capacity(graph.num_frames()),
            edges: Edges::new(graph),
            kept: (0..graph.num_frames()).map(|n| graph.is_kept(n)).collect(),
            blend: blend_frames(&graph.settings, graph.frame_time_secs),
            frame_time: graph.frame_time_secs,
        };
        for (index, (clip, meta)) in clips.iter().zip(&graph.clips).enumerate() {
            pb.add_clip(index, clip, meta)?;
        }
        Ok(pb)
    }

    fn add_clip(
        &mut self,
        index: usize,
        clip: &Clip,
        meta: &super::GraphClip,
    ) -> Result<(), GraphError> {
        let mismatch = |reason: String| GraphError::ClipMismatch {
            index,
            name: clip.name.clone(),
            reason,
        };
        if clip.skeleton.fingerprint() != self.skeleton.fingerprint() {
            return Err(mismatch(
                "a walk plays clips of one rig: retarget it onto the first clip's rig".into(),
            ));
        }
        if clip.num_frames() != meta.frames {
            return Err(mismatch(format!(
                "has {} frames, the graph expects {}",
                clip.num_frames(),
                meta.frames
            )));
        }
        let track = ClipTrack::measure(&self.skeleton, &self.body, &clip.poses);
        let end = (meta.offset + meta.frames) as u32;
        for (p, h) in track.points.iter().zip(&track.headings) {
            let to_local = h.inverse(track.up).rotation(track.up);
            self.postures.push(p.map(|q| to_local * (q - p[0])));
            self.clip_end.push(end);
            self.clip_of.push(index as u16);
        }
        self.headings.extend_from_slice(&track.headings);
        self.frames.extend(clip.poses.iter().cloned());
        Ok(())
    }

    /// The rig.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// Seconds per frame.
    pub fn frame_time_secs(&self) -> f64 {
        self.frame_time
    }

    /// Number of frames.
    pub fn num_frames(&self) -> usize {
        self.frames.len()
    }

    /// The heading frame of a node.
    pub fn heading(&self, node: usize) -> Planar {
        self.headings[node]
    }

    /// The rig's up axis.
    pub fn up(&self) -> Vec3 {
        self.body.up()
    }

    /// The outgoing edges.
    pub fn edges(&self) -> &Edges {
        &self.edges
    }

    /// Writes node `node`'s pose with its roots moved by `align` into `out`.
    pub fn sample(&self, node: usize, align: &Planar, out: &mut Pose) {
        out.copy_from(&self.frames[node]);
        let up = self.body.up();
        let turn = align.rotation(up);
        for r in &self.roots {
            let i = r.index();
            out.rotations[i] = (turn * out.rotations[i]).normalize();
            out.translations[i] = align.apply(up, out.translations[i]);
        }
    }

    /// The kept node whose posture is closest to `pose` (body points relative to the hips in
    /// the heading frame), and the alignment that puts that node where `pose` stands.
    /// `worlds` is scratch, one entry per bone; allocates nothing.
    pub fn nearest(&self, pose: &Pose, worlds: &mut [WorldTransform]) -> (usize, Planar) {
        let up = self.body.up();
        let p = self.body.points(&self.skeleton, pose, worlds);
        let h = self.body.heading(&p);
        let to_local = h.inverse(up).rotation(up);
        let local = p.map(|q| to_local * (q - p[0]));
        let mut best = (usize::MAX, f32::INFINITY);
        for (n, posture) in self.postures.iter().enumerate() {
            if !self.kept[n] {
                continue;
            }
            let d: f32 = posture
                .iter()
                .zip(&local)
                .map(|(a, b)| a.distance_squared(*b))
                .sum();
            if d < best.1 {
                best = (n, d);
            }
        }
        let node = if best.0 == usize::MAX { 0 } else { best.0 };
        let align = h.then_after(up, &self.headings[node].inverse(up));
        (node, align)
    }
}

/// What a walker does when it is not following a path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WalkerMode {
    /// Follow the path given to [`Walker::follow`], then wander.
    Follow,
    /// Take transitions at random, weighted towards the closest (∝ exp(−d / (threshold/2))).
    Wander,
}

#[derive(Debug, Clone, Copy)]
enum FadeFrom {
    /// The old clip's continuation, at its own alignment.
    Clip { node: usize, align: Planar },
    /// A fixed pose (the last live pose when the walk took over).
    Held,
}

#[derive(Debug, Clone, Copy)]
struct Fade {
    from: FadeFrom,
    step: usize,
    frames: usize,
}

/// A position on the graph that moves one frame per [`Walker::step`].
#[derive(Debug, Clone)]
pub struct Walker {
    cursor: usize,
    align: Planar,
    fade: Option<Fade>,
    since_switch: usize,
    rng: Rng,
    mode: WalkerMode,
    path: Vec<usize>,
    path_pos: usize,
    allowed: Vec<bool>,
    threshold: f32,
    new_pose: Pose,
    old_pose: Pose,
    /// The last pose written (a blend forced on mid-blend starts from it).
    shown: Pose,
    /// How far each root moved in the last step.
    root_step: Vec<Vec3>,
    /// Transitions taken so far.
    pub transitions_taken: usize,
}

impl Walker {
    /// A walker for `pb` at its first kept node, wandering with a fixed seed.
    pub fn new(graph: &MotionGraph, pb: &Playback, seed: u64) -> Walker {
        let first = graph.kept.first().map(|r| r.start).unwrap_or(0);
        Walker {
            cursor: first,
            align: Planar::IDENTITY,
            fade: None,
            since_switch: 0,
            rng: Rng::new(seed),
            mode: WalkerMode::Wander,
            path: Vec::new(),
            path_pos: 0,
            allowed: vec![true; graph.clips.len()],
            threshold: graph.settings.threshold,
            new_pose: pb.skeleton.rest_pose(),
            old_pose: pb.skeleton.rest_pose(),
            shown: pb.skeleton.rest_pose(),
            root_step: vec![Vec3::ZERO; pb.roots.len()],
            transitions_taken: 0,
        }
    }

    /// The current node.
    pub fn node(&self) -> usize {
        self.cursor
    }

    /// True while a transition (or a take-over) is still blending.
    pub fn is_blending(&self) -> bool {
        self.fade.is_some()
    }

    /// Restricts wandering to transitions into the given clips (e.g. the idle ones); leaving
    /// a clip is still allowed when its frames run out with no allowed way on.
    pub fn set_allowed_clips(&mut self, allowed: &[bool]) {
        for (a, b) in self.allowed.iter_mut().zip(allowed) {
            *a = *b;
        }
    }

    /// Puts the walker at `node` with `align`, no blend.
    pub fn start_at(&mut self, node: usize, align: Planar) {
        self.cursor = node;
        self.align = align;
        self.fade = None;
        self.since_switch = 0;
    }

    /// Takes over from `pose` (on the playback rig): starts at the nearest node, aligned to
    /// where the pose stands, and fades from the pose over `blend_frames`. Allocates nothing.
    pub fn take_over(
        &mut self,
        pb: &Playback,
        pose: &Pose,
        blend_frames: usize,
        worlds: &mut [WorldTransform],
    ) -> usize {
        let (node, align) = pb.nearest(pose, worlds);
        self.start_at(node, align);
        self.old_pose.copy_from(pose);
        self.shown.copy_from(pose);
        self.root_step.fill(Vec3::ZERO);
        self.fade = Some(Fade {
            from: FadeFrom::Held,
            step: 0,
            frames: blend_frames.max(1),
        });
        node
    }

    /// Follows `path` (nodes in play order, from [`super::walk::shortest_walk`]) from its first
    /// node, then wanders.
    pub fn follow(&mut self, path: &[usize], align: Planar) {
        self.path.clear();
        self.path.extend_from_slice(path);
        self.path_pos = 0;
        self.mode = WalkerMode::Follow;
        self.start_at(path.first().copied().unwrap_or(self.cursor), align);
    }

    /// Writes the current pose into `out` without moving.
    pub fn write(&mut self, pb: &Playback, out: &mut Pose) {
        pb.sample(self.cursor, &self.align, &mut self.new_pose);
        match self.fade {
            None => out.copy_from(&self.new_pose),
            Some(fade) => {
                match fade.from {
                    FadeFrom::Clip { node, align } => pb.sample(node, &align, &mut self.old_pose),
                    // A held pose keeps the roots moving as they were, so the path does not stop.
                    FadeFrom::Held => {
                        for (r, v) in pb.roots.iter().zip(&self.root_step) {
                            self.old_pose.translations[r.index()] += *v;
                        }
                    }
                }
                let t = fade.step as f32 / fade.frames as f32;
                let old_weight = 2.0 * t * t * t - 3.0 * t * t + 1.0;
                out.interpolate_into(&self.new_pose, &self.old_pose, old_weight);
            }
        }
        for (r, v) in pb.roots.iter().zip(&mut self.root_step) {
            *v = out.translations[r.index()] - self.shown.translations[r.index()];
        }
        self.shown.copy_from(out);
    }

    /// Moves one frame along the graph and writes the new pose into `out`. Allocates nothing.
    pub fn step(&mut self, pb: &Playback, out: &mut Pose) {
        self.advance(pb);
        self.write(pb, out);
    }

    fn advance(&mut self, pb: &Playback) {
        self.advance_fade(pb);
        let next = self.choose(pb);
        if next == self.cursor + 1 {
            self.cursor = next;
            self.since_switch += 1;
            return;
        }
        if next == self.cursor {
            return;
        }
        // Transition: `next − 1` is similar to the cursor; put its heading onto the cursor's.
        let up = pb.up();
        let onto = pb.headings[self.cursor].then_after(up, &pb.headings[next - 1].inverse(up));
        let from = if self.fade.is_some() || self.cursor + 1 >= pb.clip_end[self.cursor] as usize {
            // Forced on mid-blend (the clip ran out), or the old clip has no next frame: fade
            // from what is shown now (roots moving on), not from an old continuation the blend
            // had already half left or that would stand still.
            self.old_pose.copy_from(&self.shown);
            FadeFrom::Held
        } else {
            FadeFrom::Clip {
                node: (self.cursor + 1).min(pb.clip_end[self.cursor] as usize - 1),
                align: self.align,
            }
        };
        self.fade = Some(Fade {
            from,
            step: 0,
            frames: pb.blend,
        });
        self.align = self.align.then_after(up, &onto);
        self.cursor = next;
        self.since_switch = 0;
        self.transitions_taken += 1;
    }

    fn advance_fade(&mut self, pb: &Playback) {
        let Some(f) = self.fade.as_mut() else {
            return;
        };
        f.step += 1;
        if f.step >= f.frames {
            self.fade = None;
            return;
        }
        if let FadeFrom::Clip { node, .. } = &mut f.from {
            if *node + 1 < pb.clip_end[*node] as usize {
                *node += 1;
            } else {
                // The old clip ended: hold its last shown pose, roots moving on.
                f.from = FadeFrom::Held;
            }
        }
    }

    fn choose(&mut self, pb: &Playback) -> usize {
        if self.mode == WalkerMode::Follow {
            if let Some(&n) = self.path.get(self.path_pos + 1) {
                self.path_pos += 1;
                return n;
            }
            self.mode = WalkerMode::Wander;
        }
        let allowed = &self.allowed;
        let rule = WanderRule {
            possible: |_| true,
            preferred: |to: usize| allowed[pb.clip_of[to] as usize],
            threshold: self.threshold,
            settled: self.fade.is_none() && self.since_switch >= pb.blend,
        };
        wander_step(&pb.edges, self.cursor, &rule, &mut self.rng).unwrap_or(self.cursor)
    }
}

/// The clips moved onto one rig for playing (a graph's clips may come from different rigs;
/// a walk plays one): clips already on `rig`'s skeleton are kept, the others retargeted with
/// the automatic mapping, their floor measured over the clip. Offline; allocates.
pub fn clips_onto_rig(clips: &[Clip], rig: &Clip) -> Result<Vec<Clip>, GraphError> {
    use crate::mapping::{auto_map, MapOptions};
    use crate::retarget::{Mapping, RetargetOptions};
    let target = SkeletonView::from_clip(&rig.skeleton, &rig.poses);
    clips
        .iter()
        .enumerate()
        .map(|(index, c)| {
            if c.skeleton.fingerprint() == rig.skeleton.fingerprint() {
                return Ok(c.clone());
            }
            let fail = |e: crate::RetargetError| GraphError::ClipMismatch {
                index,
                name: c.name.clone(),
                reason: format!("cannot retarget it onto the playing rig: {e}"),
            };
            let source = SkeletonView::from_clip(&c.skeleton, &c.poses);
            let table = auto_map(&source, &target, &MapOptions::default());
            let opts = RetargetOptions {
                frame_time_secs: c.frame_time_secs as f32,
                ..RetargetOptions::default()
            };
            let mut m =
                Mapping::build(&[&c.skeleton], &rig.skeleton, &table, &opts).map_err(fail)?;
            if let Some(floor) = m.measure_source_floor(&c.poses) {
                m.set_source_floor_y(floor);
            }
            m.apply_clip(c).map_err(fail)
        })
        .collect()
}
