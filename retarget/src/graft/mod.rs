//! Grafting (seed 002; Heck, Kovar, Gleicher 2006): the upper body of one clip on the legs of
//! another, in step.
//!
//! ```text
//!  graft clip (already retargeted onto the locomotion's rig) + its plants (from its source)
//!  locomotion clip + its plants
//!     │ body::BodySplit        cut at the waist (analysis roles): lower = pelvis, legs;
//!     │                        upper = spine above it, arms, head; blend bones
//!     │ features               per half: core joints in the pelvis's heading frame + speeds
//!     │ cluster                both clips' frames pooled, k-means → labels; one cluster
//!     │                        graph per clip; shared clusters = transitions
//!     │ warp                   landings (plant starts) paired outwards from the best
//!     │                        transition at a landing of the same foot; piecewise-linear
//!     │                        clock from the locomotion to the graft, slope in [0.5, 2]
//!     ▼ splice::Splice         per locomotion frame: graft sampled at the warped time,
//!                              upper locals onto the locomotion pose, torso turned to its
//!                              heading, spine blended over a few bones
//! ```
//!
//! The output is on the locomotion's rig with its frame times; its legs and root are the
//! locomotion's exactly, so its footplants are the locomotion's. The live counterpart
//! (a looping locomotion clip kept in phase) is [`gait::GaitLoop`]; the splice is shared.

pub mod body;
pub mod cluster;
pub mod features;
pub mod gait;
pub mod splice;
pub mod warp;

use std::sync::Arc;

pub use body::{BodySplit, Half};
pub use cluster::{cluster_pair, ClusterGraph, Clustering};
pub use features::{features, Features};
pub use gait::GaitLoop;
pub use splice::Splice;
pub use warp::{pair_from, plant_events, PlantEvent, TimeWarp};

use crate::clip::Clip;
use crate::footplant::PlantTrack;

/// Why a graft cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraftError {
    /// The skeleton cannot be cut at the waist.
    #[error("cannot cut the body at the waist: {0}")]
    Body(String),
    /// The two clips are not on one skeleton (retarget the graft first).
    #[error(
        "the graft and the locomotion must be on one skeleton ({graft} vs {locomotion} bones)"
    )]
    Skeletons {
        /// Bones of the graft clip's skeleton.
        graft: usize,
        /// Bones of the locomotion clip's skeleton.
        locomotion: usize,
    },
    /// A clip without frames.
    #[error("the {0} clip has no frames")]
    Empty(&'static str),
    /// A locomotion clip to loop in which no foot lands twice.
    #[error("the locomotion clip has no full stride to loop (no foot lands twice)")]
    NoStride,
}

/// How a graft is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraftSettings {
    /// Clusters per body half (both clips pooled).
    pub clusters: usize,
    /// Spine bones over which the graft's rotation blends in.
    pub blend_bones: usize,
}

impl Default for GraftSettings {
    fn default() -> Self {
        GraftSettings {
            clusters: 12,
            blend_bones: 3,
        }
    }
}

/// What the planning decided (the summary a user sees).
#[derive(Debug, Clone, PartialEq)]
pub struct GraftPlan {
    /// The clock from the locomotion to the graft.
    pub warp: TimeWarp,
    /// Landings (plant starts) found in the graft and in the locomotion.
    pub plants: (usize, usize),
    /// Landings paired between the two (the warp's knots).
    pub paired: usize,
    /// The anchor: (locomotion frame, graft frame) of the transition the pairing started from.
    pub anchor: Option<(usize, usize)>,
    /// The anchor's frames share a lower-body cluster (a transition in the cluster graphs).
    pub anchor_is_transition: bool,
    /// Lower- and upper-body clusters both clips visit, of `GraftSettings::clusters` each.
    pub shared_clusters: (usize, usize),
}

/// Plans a graft: `graft` (on `lower`'s skeleton, its plants from its own source) onto the
/// locomotion `lower`.
pub fn plan(
    graft: (&Clip, &PlantTrack),
    lower: (&Clip, &PlantTrack),
    split: &BodySplit,
    settings: &GraftSettings,
) -> Result<GraftPlan, GraftError> {
    let ((g, g_plants), (l, l_plants)) = (graft, lower);
    check(g, l)?;
    let half_features =
        |c: &Clip, half| features(&c.skeleton, &c.poses, c.frame_time_secs, split, half);
    let (gl, ll) = (half_features(g, Half::Lower), half_features(l, Half::Lower));
    let (gu, lu) = (half_features(g, Half::Upper), half_features(l, Half::Upper));
    let lower_c = cluster_pair(&gl, &ll, settings.clusters);
    let upper_c = cluster_pair(&gu, &lu, settings.clusters);
    let shared = |c: &Clustering| {
        let (a, b) = (
            ClusterGraph::new(&c.first, c.num_clusters),
            ClusterGraph::new(&c.second, c.num_clusters),
        );
        a.shared(&b).len()
    };
    let (g_events, l_events) = (plant_events(g_plants), plant_events(l_plants));
    let g_end = (g.num_frames() - 1) as f64 * g.frame_time_secs;
    let anchor = best_anchor(&l_events, &g_events, &lower_c, (&ll, &gl));
    let (pairs, anchor, transition) = match anchor {
        Some((at, t)) => {
            let pairs = pair_from(&l_events, &g_events, at);
            let anchor = (l_events[at.0].frame, g_events[at.1].frame);
            (pairs, Some(anchor), t)
        }
        // No landing to synchronise on (a standing clip): both play from their start.
        None => (vec![(0, 0)], None, false),
    };
    Ok(GraftPlan {
        warp: TimeWarp::from_pairs(&pairs, l.frame_time_secs, g.frame_time_secs, g_end),
        plants: (g_events.len(), l_events.len()),
        paired: if anchor.is_some() { pairs.len() } else { 0 },
        anchor,
        anchor_is_transition: transition,
        shared_clusters: (shared(&lower_c), shared(&upper_c)),
    })
}

/// The anchor landing pair (indices into the locomotion's and the graft's landings, same
/// foot) and whether it is a transition: the pair that pairs the most landings, then one whose
/// lower-body clusters are shared, then the nearest lower-body poses.
fn best_anchor(
    lower: &[PlantEvent],
    graft: &[PlantEvent],
    clusters: &Clustering,
    (lower_features, graft_features): (&Features, &Features),
) -> Option<((usize, usize), bool)> {
    let mut best: Option<(usize, bool, f32, (usize, usize))> = None;
    for (i, le) in lower.iter().enumerate() {
        for (j, ge) in graft
            .iter()
            .enumerate()
            .filter(|(_, ge)| ge.foot == le.foot)
        {
            let paired = pair_from(lower, graft, (i, j)).len();
            let transition = clusters.first[ge.frame] == clusters.second[le.frame];
            let distance = graft_features.distance2(ge.frame, lower_features, le.frame);
            let better = match best {
                None => true,
                Some((p, t, d, _)) => (paired, transition, -distance) > (p, t, -d),
            };
            if better {
                best = Some((paired, transition, distance, (i, j)));
            }
        }
    }
    best.map(|(_, t, _, at)| (at, t))
}

/// Makes the grafted clip: per locomotion frame, the graft sampled at the warped time and
/// spliced on. `progress(done, total)` is called after every frame.
pub fn synthesize(
    plan: &GraftPlan,
    graft: &Clip,
    lower: &Clip,
    split: &BodySplit,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Clip, GraftError> {
    check(graft, lower)?;
    let mut splice = Splice::new(&lower.skeleton, split.clone());
    let mut sampled = lower.skeleton.rest_pose();
    let mut out = lower.skeleton.rest_pose();
    let n = lower.num_frames();
    let mut poses = Vec::with_capacity(n);
    for (f, p) in lower.poses.iter().enumerate() {
        graft.sample_into(plan.warp.at(f as f64 * lower.frame_time_secs), &mut sampled);
        splice.apply(p, &sampled, &mut out);
        poses.push(out.clone());
        progress(f + 1, n);
    }
    Clip::new(
        format!("{} + {}", graft.name, lower.name),
        Arc::clone(&lower.skeleton),
        poses,
        lower.frame_time_secs,
    )
    .map_err(|_| GraftError::Empty("locomotion"))
}

fn check(graft: &Clip, lower: &Clip) -> Result<(), GraftError> {
    if graft.num_frames() == 0 {
        return Err(GraftError::Empty("graft"));
    }
    if lower.num_frames() == 0 {
        return Err(GraftError::Empty("locomotion"));
    }
    if graft.skeleton.fingerprint() != lower.skeleton.fingerprint() {
        return Err(GraftError::Skeletons {
            graft: graft.skeleton.num_bones(),
            locomotion: lower.skeleton.num_bones(),
        });
    }
    Ok(())
}
