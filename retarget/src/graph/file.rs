//! The `.rmg` motion-graph file: versioned JSON (format in `retarget/GRAPH.md`). Reading
//! checks everything a walk relies on (ranges inside the clips, transitions between kept
//! nodes, finite distances), so a damaged or hand-edited file is an error, never a panic.

use serde::{Deserialize, Serialize};

use super::build::{GraphClip, GraphSettings, MotionGraph, Transition};
use super::GraphError;

/// The `format` field of every graph file.
pub const FORMAT: &str = "rigcast-motion-graph";
/// The version this build writes and reads.
pub const VERSION: u32 = 1;

#[derive(Serialize, Deserialize)]
struct FileV1 {
    format: String,
    version: u32,
    frame_time_secs: f64,
    settings: GraphSettings,
    clips: Vec<GraphClip>,
    /// `[start, end)` node ranges of the kept component.
    kept: Vec<[usize; 2]>,
    /// `[from, to, distance]`.
    transitions: Vec<(u32, u32, f32)>,
    similar_pairs: usize,
    components: usize,
}

#[derive(Deserialize)]
struct Header {
    format: String,
    version: u32,
}

impl MotionGraph {
    /// The graph as `.rmg` JSON.
    pub fn to_json(&self) -> String {
        let file = FileV1 {
            format: FORMAT.into(),
            version: VERSION,
            frame_time_secs: self.frame_time_secs,
            settings: self.settings,
            clips: self.clips.clone(),
            kept: self.kept.iter().map(|r| [r.start, r.end]).collect(),
            transitions: self
                .transitions
                .iter()
                .map(|t| (t.from, t.to, t.distance))
                .collect(),
            similar_pairs: self.similar_pairs,
            components: self.components,
        };
        // Plain data with string keys: serialising cannot fail.
        serde_json::to_string(&file).unwrap_or_default()
    }

    /// Reads `.rmg` JSON, checking it.
    pub fn from_json(text: &str) -> Result<MotionGraph, GraphError> {
        let bad = |m: String| GraphError::BadFile(m);
        let head: Header = serde_json::from_str(text).map_err(|e| bad(short(&e)))?;
        if head.format != FORMAT {
            return Err(bad(format!("format is {:?}, not {FORMAT:?}", head.format)));
        }
        if head.version != VERSION {
            return Err(bad(format!(
                "version {} (this rigcast reads version {VERSION})",
                head.version
            )));
        }
        let f: FileV1 = serde_json::from_str(text).map_err(|e| bad(short(&e)))?;
        let graph = MotionGraph {
            settings: f.settings,
            frame_time_secs: f.frame_time_secs,
            clips: f.clips,
            transitions: f
                .transitions
                .into_iter()
                .map(|(from, to, distance)| Transition { from, to, distance })
                .collect(),
            kept: f.kept.into_iter().map(|[a, b]| a..b).collect(),
            similar_pairs: f.similar_pairs,
            components: f.components,
        };
        check(&graph).map_err(bad)?;
        Ok(graph)
    }
}

fn short(e: &serde_json::Error) -> String {
    format!("line {} column {}: {}", e.line(), e.column(), e)
}

fn check(g: &MotionGraph) -> Result<(), String> {
    if !(g.frame_time_secs.is_finite() && g.frame_time_secs > 0.0) {
        return Err(format!(
            "frame_time_secs {} is not positive",
            g.frame_time_secs
        ));
    }
    let mut next = 0;
    for (i, c) in g.clips.iter().enumerate() {
        if c.offset != next {
            return Err(format!(
                "clip {i} starts at node {}, expected {next}",
                c.offset
            ));
        }
        next = c
            .offset
            .checked_add(c.frames)
            .ok_or("clip frames overflow")?;
    }
    let mut end = 0;
    for r in &g.kept {
        if r.start < end || r.end <= r.start || r.end > next {
            return Err(format!(
                "kept range {}..{} is not sorted, empty or past the {next} nodes",
                r.start, r.end
            ));
        }
        end = r.end;
    }
    let mut last = 0;
    for t in &g.transitions {
        let (a, b) = (t.from as usize, t.to as usize);
        if !(g.is_kept(a) && g.is_kept(b) && t.distance.is_finite()) || t.from < last {
            return Err(format!(
                "transition {a} → {b} is unsorted, leaves the kept nodes or has no distance"
            ));
        }
        last = t.from;
    }
    Ok(())
}
