//! Motion-graph files and their clips, read by `rigcast graph` and by the idle fallback at
//! start: clip references `FILE` or `FILE#ANIMATION` (a glTF file's animation by name or
//! index), and a `.rmg` file read with a short error naming it.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context};
use rigcast_retarget::graph::{clip_fingerprint, MotionGraph};
use rigcast_retarget::Clip;
use rigcast_sources::{load_clip_with, LoadOptions};

/// A clip named on the command line or in a graph file.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipSpec {
    /// The file.
    pub path: PathBuf,
    /// A glTF animation, by name or index.
    pub animation: Option<String>,
}

impl ClipSpec {
    /// Parses `FILE` or `FILE#ANIMATION`.
    pub fn parse(s: &str) -> ClipSpec {
        match s.rsplit_once('#') {
            Some((file, anim)) if !anim.is_empty() => ClipSpec {
                path: PathBuf::from(file),
                animation: Some(anim.to_string()),
            },
            _ => ClipSpec {
                path: PathBuf::from(s),
                animation: None,
            },
        }
    }

    /// Back to `FILE#ANIMATION` text, the path made absolute (so a graph file can be used
    /// from any directory).
    pub fn to_text(&self) -> String {
        let path = std::fs::canonicalize(&self.path).unwrap_or_else(|_| self.path.clone());
        match &self.animation {
            Some(a) => format!("{}#{a}", path.display()),
            None => path.display().to_string(),
        }
    }

    /// Loads the clip, naming it `stem` or `stem#animation`.
    pub fn load(&self) -> anyhow::Result<Clip> {
        let opts = LoadOptions {
            animation: self.animation.clone(),
            ..LoadOptions::default()
        };
        let mut clip = load_clip_with(&self.path, &opts).map_err(|e| anyhow!("{e}"))?;
        if clip.num_frames() == 0 {
            return Err(anyhow!("{} has no animation frames", self.path.display()));
        }
        clip.name = name(&self.path, self.animation.as_deref());
        Ok(clip)
    }
}

fn name(path: &Path, animation: Option<&str>) -> String {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("clip");
    match animation {
        Some(a) => format!("{stem}#{a}"),
        None => stem.to_string(),
    }
}

/// Where clip `i` of `graph` is.
pub fn clip_spec(graph: &MotionGraph, i: usize) -> anyhow::Result<ClipSpec> {
    let c = &graph.clips[i];
    let p = c
        .path
        .as_deref()
        .ok_or_else(|| anyhow!("the graph does not say where clip {i} ({}) is", c.name))?;
    Ok(ClipSpec::parse(p))
}

/// The graph's clips, read again and checked against their fingerprints.
pub fn load_graph_clips(graph: &MotionGraph) -> anyhow::Result<Vec<Clip>> {
    (0..graph.clips.len())
        .map(|i| {
            let clip = clip_spec(graph, i)?.load()?;
            let want = &graph.clips[i].fingerprint;
            if &format!("{:016x}", clip_fingerprint(&clip)) != want {
                bail!(
                    "clip {i} ({}) changed since the graph was built; rebuild it",
                    graph.clips[i].name
                );
            }
            Ok(clip)
        })
        .collect()
}

/// Reads a graph file with a short error naming it.
pub fn read_graph(path: &Path) -> anyhow::Result<MotionGraph> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    MotionGraph::from_json(&text).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// A clip of `graph` by number or name.
pub fn clip_index(graph: &MotionGraph, s: &str) -> anyhow::Result<usize> {
    if let Ok(i) = s.parse::<usize>() {
        if i < graph.clips.len() {
            return Ok(i);
        }
        bail!(
            "clip {i} does not exist (the graph has {})",
            graph.clips.len()
        );
    }
    graph
        .clips
        .iter()
        .position(|c| c.name == s)
        .ok_or_else(|| anyhow!("no clip is named {s:?}"))
}

/// Per clip of `graph`: may a walk switch into it by choice (every clip when `names` is
/// empty; else the clips named, by number or name).
pub fn clip_mask(graph: &MotionGraph, names: &[String]) -> anyhow::Result<Vec<bool>> {
    if names.is_empty() {
        return Ok(vec![true; graph.clips.len()]);
    }
    let mut mask = vec![false; graph.clips.len()];
    for n in names {
        mask[clip_index(graph, n.trim())?] = true;
    }
    Ok(mask)
}

#[cfg(test)]
mod clip_tests {
    use super::*;
    use rigcast_retarget::graph::{GraphClip, GraphSettings};

    fn graph(names: &[&str]) -> MotionGraph {
        MotionGraph {
            settings: GraphSettings::default(),
            frame_time_secs: 1.0 / 30.0,
            clips: names
                .iter()
                .enumerate()
                .map(|(i, n)| GraphClip {
                    name: n.to_string(),
                    path: None,
                    fingerprint: String::new(),
                    frames: 10,
                    offset: 10 * i,
                })
                .collect(),
            transitions: Vec::new(),
            // One kept range over every frame, not the numbers 0 to n.
            kept: std::iter::once(0..10 * names.len()).collect(),
            similar_pairs: 0,
            components: 1,
        }
    }

    #[test]
    fn clips_are_named_by_number_or_name_and_unknown_ones_refused() {
        let g = graph(&["idle", "walk", "idle2"]);
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(clip_mask(&g, &[]).unwrap(), [true, true, true]);
        let mask = clip_mask(&g, &names(&["idle", " 2"])).unwrap();
        assert_eq!(mask, [true, false, true]);
        let e = clip_mask(&g, &names(&["run"])).unwrap_err();
        assert!(e.to_string().contains("no clip is named \"run\""), "{e}");
        let e = clip_mask(&g, &names(&["3"])).unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
    }
}
