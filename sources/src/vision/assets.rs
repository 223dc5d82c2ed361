//! Where the vision assets live: the cache directory filled by `scripts/setup-vision.sh`.
//!
//! `$RIGCAST_HOME/vision/` (default `~/.cache/rigcast/vision/`) holds `lib/libonnxruntime.so`,
//! `models/pose_landmark_{lite,full,heavy}.onnx` and `pose2sim/cam0N.mp4`. Nothing here
//! downloads anything: a missing file is a [`VisionError::NotSetUp`] telling the user which
//! command to run.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use super::error::VisionError;

/// Which BlazePose landmark model to run (speed versus accuracy).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModelKind {
    /// Fastest (~5.5 MB).
    #[default]
    Lite,
    /// Middle.
    Full,
    /// Most accurate, slowest.
    Heavy,
}

impl ModelKind {
    /// `lite`, `full` or `heavy`.
    pub fn as_str(self) -> &'static str {
        match self {
            ModelKind::Lite => "lite",
            ModelKind::Full => "full",
            ModelKind::Heavy => "heavy",
        }
    }
}

impl FromStr for ModelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "lite" => Ok(ModelKind::Lite),
            "full" => Ok(ModelKind::Full),
            "heavy" => Ok(ModelKind::Heavy),
            other => Err(format!(
                "unknown model {other:?}: expected lite, full or heavy"
            )),
        }
    }
}

/// Paths of the installed vision assets.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VisionAssets {
    /// `$RIGCAST_HOME/vision`.
    pub root: PathBuf,
}

impl VisionAssets {
    /// The default location: `$RIGCAST_HOME/vision`, or `~/.cache/rigcast/vision`.
    pub fn from_env() -> VisionAssets {
        let home = std::env::var_os("RIGCAST_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/rigcast")))
            .unwrap_or_else(|| PathBuf::from(".cache/rigcast"));
        VisionAssets {
            root: home.join("vision"),
        }
    }

    /// Assets under an explicit directory (tests).
    pub fn at(root: impl Into<PathBuf>) -> VisionAssets {
        VisionAssets { root: root.into() }
    }

    /// The ONNX Runtime shared library.
    pub fn runtime_library(&self) -> PathBuf {
        self.root.join("lib/libonnxruntime.so")
    }

    /// A landmark model.
    pub fn landmark_model(&self, kind: ModelKind) -> PathBuf {
        self.root
            .join(format!("models/pose_landmark_{}.onnx", kind.as_str()))
    }

    /// The person detector.
    pub fn detector_model(&self) -> PathBuf {
        self.root.join("models/pose_detection.onnx")
    }

    /// One of the pose2sim two-person demo videos (`camera` 1..=4).
    pub fn pose2sim_multi_video(&self, camera: u32) -> PathBuf {
        self.root.join(format!("pose2sim/multi_cam{camera:02}.mp4"))
    }

    /// One of the pose2sim demo videos (`camera` 1..=4).
    pub fn pose2sim_video(&self, camera: u32) -> PathBuf {
        self.root.join(format!("pose2sim/cam{camera:02}.mp4"))
    }

    /// Checks that the setup script completed and returns `path` if it exists.
    pub fn require(&self, path: PathBuf, what: &'static str) -> Result<PathBuf, VisionError> {
        let ready = self.root.join("READY");
        if !ready.is_file() {
            return Err(VisionError::NotSetUp {
                path: ready,
                what: "setup marker",
            });
        }
        if !path.is_file() {
            return Err(VisionError::NotSetUp { path, what });
        }
        Ok(path)
    }

    /// True when the setup script has completed here.
    pub fn is_ready(&self) -> bool {
        self.root.join("READY").is_file()
    }
}

/// Finds `scripts/setup-vision.sh` relative to a directory inside the repository (walks up).
pub fn find_setup_script(start: &Path) -> Option<PathBuf> {
    start
        .ancestors()
        .map(|d| d.join("scripts/setup-vision.sh"))
        .find(|p| p.is_file())
}
