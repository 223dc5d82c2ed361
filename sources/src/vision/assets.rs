//! Where the vision assets live: the cache directory filled by `scripts/setup-vision.sh`.
//!
//! `$RIGCAST_HOME/vision/` (default `~/.cache/rigcast/vision/`) holds `lib/libonnxruntime.so`,
//! `models/pose_landmark_{lite,full,heavy}.onnx` (as converted) with their pruned copies
//! `pose_landmark_{lite,full,heavy}_pruned.onnx` (only the outputs rigcast reads, without
//! the segmentation mask: the same numbers in about half the time), the int8 copy `pose_landmark_full_int8.onnx`,
//! the detector `pose_detection.onnx`, copies of the pruned models and the detector that
//! take their input channels first (`pose_landmark_{lite,full,heavy}_planar.onnx`,
//! `pose_detection_planar.onnx`: the same numbers for a little less work), and
//! `pose2sim/cam0N.mp4`. Nothing here downloads anything: a missing file is a
//! [`VisionError::NotSetUp`] telling the user which command to run.

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
    /// `full` quantised to int8 at setup time (calibrated on real footage): as fast as lite,
    /// but its landmarks are off `full`'s by 14 % of the torso on average (BENCHMARKS.md), so
    /// it is only ever used when asked for by name.
    FullInt8,
}

impl ModelKind {
    /// `lite`, `full` or `heavy`.
    pub fn as_str(self) -> &'static str {
        match self {
            ModelKind::Lite => "lite",
            ModelKind::Full => "full",
            ModelKind::Heavy => "heavy",
            ModelKind::FullInt8 => "full-int8",
        }
    }

    /// The file stem under `models/`: `pose_landmark_{stem}`.
    fn file_stem(self) -> &'static str {
        match self {
            ModelKind::Lite => "lite",
            ModelKind::Full => "full",
            ModelKind::Heavy => "heavy",
            ModelKind::FullInt8 => "full_int8",
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
            "full-int8" => Ok(ModelKind::FullInt8),
            other => Err(format!(
                "unknown model {other:?}: expected lite, full, heavy or full-int8"
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

    /// The file to load for a landmark model: the pruned copy when setup made one (same
    /// landmarks, about half the work: the converted model also computes a segmentation mask,
    /// which ONNX Runtime runs even when nobody reads it), and of it the copy taking its
    /// input channels first when there (setup's derivation 5 on: the same numbers, without
    /// a transpose and a pad of the input a run), else the model as converted. The int8
    /// model exists only pruned.
    pub fn landmark_model(&self, kind: ModelKind) -> PathBuf {
        let pruned = self.pruned_landmark_model(kind);
        if kind == ModelKind::FullInt8 {
            return pruned;
        }
        let planar = Self::planar_copy(&pruned);
        if planar.is_file() {
            return planar;
        }
        if pruned.is_file() {
            return pruned;
        }
        self.converted_landmark_model(kind)
    }

    /// Where setup puts the copy of `model` (`…_pruned.onnx` or the detector) taking its input
    /// channels first (`scripts/planar_input.py`).
    fn planar_copy(model: &Path) -> PathBuf {
        let stem = model
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default();
        let stem = stem.strip_suffix("_pruned").unwrap_or(stem);
        model.with_file_name(format!("{stem}_planar.onnx"))
    }

    /// A landmark model as converted from MediaPipe's TFLite (all five outputs).
    pub fn converted_landmark_model(&self, kind: ModelKind) -> PathBuf {
        self.root
            .join(format!("models/pose_landmark_{}.onnx", kind.file_stem()))
    }

    /// The copy of a landmark model with only the landmark, presence, world and heatmap
    /// outputs (setup's derivations before 3 left the heatmaps out too; from 4 the heatmaps
    /// hold only the body's landmarks, shoulders to feet, the ones refined).
    pub fn pruned_landmark_model(&self, kind: ModelKind) -> PathBuf {
        let name = match kind {
            ModelKind::FullInt8 => "pose_landmark_full_int8.onnx".to_string(),
            _ => format!("pose_landmark_{}_pruned.onnx", kind.file_stem()),
        };
        self.root.join("models").join(name)
    }

    /// The person detector: the copy taking its input channels first when setup made one
    /// (derivation 5 on: the same detections for a little less work), else as converted.
    pub fn detector_model(&self) -> PathBuf {
        let converted = self.root.join("models/pose_detection.onnx");
        let planar = Self::planar_copy(&converted);
        if planar.is_file() {
            return planar;
        }
        converted
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

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn model_names_round_trip() {
        for kind in [
            ModelKind::Lite,
            ModelKind::Full,
            ModelKind::Heavy,
            ModelKind::FullInt8,
        ] {
            assert_eq!(kind.as_str().parse::<ModelKind>(), Ok(kind));
        }
        assert!("int8"
            .parse::<ModelKind>()
            .unwrap_err()
            .contains("full-int8"));
    }

    #[test]
    fn the_pruned_copy_is_loaded_when_there_and_int8_only_by_name() {
        let root = std::env::temp_dir().join(format!("rigcast-assets-{}", std::process::id()));
        std::fs::create_dir_all(root.join("models")).unwrap();
        let assets = VisionAssets::at(&root);
        let converted = root.join("models/pose_landmark_full.onnx");
        assert_eq!(assets.landmark_model(ModelKind::Full), converted);
        let pruned = root.join("models/pose_landmark_full_pruned.onnx");
        std::fs::write(&pruned, b"x").unwrap();
        assert_eq!(assets.landmark_model(ModelKind::Full), pruned);
        let planar = root.join("models/pose_landmark_full_planar.onnx");
        std::fs::write(&planar, b"x").unwrap();
        assert_eq!(assets.landmark_model(ModelKind::Full), planar);
        assert_eq!(
            assets.landmark_model(ModelKind::Lite),
            root.join("models/pose_landmark_lite.onnx")
        );
        // The int8 file never stands in for `full`, and `full-int8` never falls back to float.
        assert_eq!(
            assets.landmark_model(ModelKind::FullInt8),
            root.join("models/pose_landmark_full_int8.onnx")
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn the_planar_detector_is_loaded_when_there() {
        let root = std::env::temp_dir().join(format!("rigcast-det-{}", std::process::id()));
        std::fs::create_dir_all(root.join("models")).unwrap();
        let assets = VisionAssets::at(&root);
        assert_eq!(
            assets.detector_model(),
            root.join("models/pose_detection.onnx")
        );
        let planar = root.join("models/pose_detection_planar.onnx");
        std::fs::write(&planar, b"x").unwrap();
        assert_eq!(assets.detector_model(), planar);
        std::fs::remove_dir_all(&root).unwrap();
    }
}
