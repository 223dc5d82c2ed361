//! Clip arguments: `FILE` or `FILE#ANIMATION` (a glTF file's animation by name or index).

use std::path::{Path, PathBuf};

use anyhow::anyhow;
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
