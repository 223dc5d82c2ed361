//! Motion graphs (Kovar, Gleicher and Pighin 2002; seed 001): new motion from recorded clips
//! by jumping between frames that look alike.
//!
//! ```text
//!  clips (any humanoid rigs) ─▶ body       13 body points found by analysis role, heading
//!                                          frame per frame (floor position + facing)
//!                            ─▶ features   per frame: points over a ±window/2 window in the
//!                                          centre frame's heading frame + velocities, in leg
//!                                          lengths — one vector, so distance = Euclidean
//!                            ─▶ search     coarse grid (1/30 s) with early-exit distances,
//!                                          refined by descent to full-resolution local minima
//!                                          below the threshold
//!                            ─▶ build      nodes = frames, edges = clip successors + one
//!                                          transition each way per similar pair, pruned to
//!                                          the largest strongly connected component
//!                                          (petgraph Tarjan): no walk dead-ends
//!  MotionGraph ─▶ walk        Dijkstra/A* between two frames (petgraph), or wandering
//!                             (random, ∝ exp(−d), optionally kept inside chosen clips)
//!              ─▶ timed       a wandering walk that is at a chosen frame at a chosen time
//!                             (exact-length reachability layers from the goal)
//!              ─▶ play        Walker: per frame, root aligned heading-to-heading at each
//!                             transition, Kovar's cross-fade (α = 2t³ − 3t² + 1) over the
//!                             blend time; allocates nothing per step (live fallback)
//!              ─▶ file        `.rmg`, versioned JSON (see `retarget/GRAPH.md`)
//! ```
//!
//! Nodes are frames of the clips after resampling to the first clip's frame rate. A
//! transition edge `u → v` means "after frame `u`, play frame `v`"; it exists because `u`
//! and `v − 1` are similar (their distance is the edge's cost), so the root is aligned from
//! `v − 1`'s heading onto `u`'s.

pub mod body;
pub mod build;
pub mod features;
pub mod file;
pub mod play;
pub mod search;
pub mod timed;
pub mod walk;

pub use body::{BodyPoints, Planar};
pub use build::{clip_fingerprint, GraphClip, GraphSettings, MotionGraph, Transition};
pub use play::{Playback, Walker, WalkerMode};
pub use timed::{timed_walk, TimedWalk};

use thiserror::Error;

/// What can go wrong building, reading or walking a motion graph.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GraphError {
    /// A graph needs at least one clip with frames.
    #[error("no frames: a motion graph needs at least one clip with motion")]
    NoFrames,
    /// A clip's rig lacks a body part the comparison uses.
    #[error("the rig has no {part} (motion graphs need a two-legged, two-armed body)")]
    MissingBodyPart {
        /// which part
        part: String,
    },
    /// A clip is named that the graph does not hold, or with other frames.
    #[error("clip {index} ({name}): {reason}")]
    ClipMismatch {
        /// index of the clip
        index: usize,
        /// its name
        name: String,
        /// what differs
        reason: String,
    },
    /// A frame reference is outside the graph or was pruned.
    #[error("frame {frame} is not a node of the graph ({reason})")]
    NotANode {
        /// the global frame index
        frame: usize,
        /// why
        reason: &'static str,
    },
    /// No walk connects the two frames.
    #[error("no walk from frame {from} to frame {to}")]
    NoWalk {
        /// start
        from: usize,
        /// end
        to: usize,
    },
    /// A timed walk asked to arrive sooner than the quickest walk can.
    #[error(
        "no walk from frame {from} reaches frame {to} in {:.3} s ({asked_frames} frames): the \
         quickest takes {:.3} s ({quickest_frames} frames), {:.3} s more",
        *.asked_frames as f64 * .frame_time_secs,
        *.quickest_frames as f64 * .frame_time_secs,
        (*.quickest_frames - *.asked_frames) as f64 * .frame_time_secs
    )]
    ArrivalTooSoon {
        /// start
        from: usize,
        /// goal
        to: usize,
        /// the arrival asked for, frames after the start
        asked_frames: usize,
        /// the quickest walk's frames
        quickest_frames: usize,
        /// seconds per frame
        frame_time_secs: f64,
    },
    /// Settings out of range.
    #[error("bad graph setting: {0}")]
    BadSetting(String),
    /// A graph file that cannot be read.
    #[error("not a valid motion graph file: {0}")]
    BadFile(String),
}
