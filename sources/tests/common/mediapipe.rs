//! MediaPipe Pose 0.10.14 (Python, its defaults: one person, full model), the anchor the
//! vision judges compare rigcast with: a program rigcast shares no code with (its own runtime,
//! tracker, crops and smoothing), installed by `scripts/setup-mediapipe.sh` in a private venv
//! and run through `scripts/bench_mediapipe.py`. Included by path in the vision tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Image points of one person in one frame (source pixels) with visibilities.
pub type Points = Vec<[f32; 3]>;

/// MediaPipe's run over one clip.
pub struct MediaPipeRun {
    /// Per frame: the 33 image landmarks, or `None` where nobody was found.
    pub frames: Vec<Option<Points>>,
    /// Per frame: the 33 world landmarks (metres, hip-centred, x right and y down in the
    /// picture, z away from the camera).
    pub world: Vec<Option<Points>>,
    /// The source's size in pixels.
    pub width: f32,
    pub height: f32,
    /// Frames a second with decoding.
    pub fps: f64,
    /// Read back from `RIGCAST_MEDIAPIPE_CACHE` (its frame rate is from another run).
    pub cached: bool,
}

/// The venv's python with MediaPipe 0.10.14, or the reason there is none.
pub fn mediapipe_python() -> Result<PathBuf, String> {
    let python = std::env::var_os("RIGCAST_MEDIAPIPE_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let home = std::env::var_os("RIGCAST_HOME")
                .map(PathBuf::from)
                .unwrap_or_else(|| {
                    PathBuf::from(std::env::var_os("HOME").unwrap_or_default())
                        .join(".cache/rigcast")
                });
            home.join("mediapipe-0.10.14/bin/python")
        });
    let ok = Command::new(&python)
        .args(["-c", "import mediapipe"])
        .output()
        .is_ok_and(|o| o.status.success());
    if ok {
        Ok(python)
    } else {
        Err(format!(
            "MediaPipe 0.10.14 is not installed at {} (scripts/setup-mediapipe.sh installs it)",
            python.display()
        ))
    }
}

/// Where this run's landmarks and summary line go: `RIGCAST_MEDIAPIPE_CACHE` (a folder:
/// `CLIP.json`, its landmarks over every frame, and `CLIP.txt`, its summary line, kept between
/// runs while iterating on the tracker) or a temporary pair removed after reading.
fn outputs(path: &Path, model: &str) -> (PathBuf, PathBuf, bool) {
    let mut name = path.file_name().unwrap().to_string_lossy().into_owned();
    if model != "full" {
        name = format!("{name}.{model}");
    }
    match std::env::var_os("RIGCAST_MEDIAPIPE_CACHE").map(PathBuf::from) {
        Some(dir) => (
            dir.join(format!("{name}.json")),
            dir.join(format!("{name}.txt")),
            true,
        ),
        None => {
            let temp = std::env::temp_dir().join(format!(
                "rigcast-mediapipe-{}-{}-{name}",
                std::process::id(),
                path.parent()
                    .and_then(Path::file_name)
                    .unwrap_or_default()
                    .to_string_lossy()
            ));
            (
                temp.with_extension("json"),
                temp.with_extension("txt"),
                false,
            )
        }
    }
}

/// A cache entry is usable when both files exist and the landmarks hold the world points
/// (files from before they were written are made again).
fn cached(json: &Path, text: &Path) -> bool {
    text.is_file() && std::fs::read_to_string(json).is_ok_and(|j| j.contains("\"world\""))
}

fn points(frames: &serde_json::Value, max: Option<usize>) -> Vec<Option<Points>> {
    let Some(frames) = frames.as_array() else {
        return Vec::new();
    };
    frames
        .iter()
        .take(max.unwrap_or(usize::MAX))
        .map(|f| {
            f.as_array().map(|pts| {
                pts.iter()
                    .map(|p| {
                        let v = |i: usize| p[i].as_f64().unwrap() as f32;
                        [v(0), v(1), v(2)]
                    })
                    .collect()
            })
        })
        .collect()
}

/// MediaPipe's run over `path` (its first `max` frames): in this run, or read back from
/// `RIGCAST_MEDIAPIPE_CACHE` while iterating on the tracker.
pub fn run_mediapipe(python: &Path, path: &Path, max: Option<usize>) -> MediaPipeRun {
    run_mediapipe_model(python, path, max, "full")
}

/// [`run_mediapipe`] with MediaPipe's `model` (`full` or `lite`; a cache keeps lite's landmarks
/// as `CLIP.lite.json`).
pub fn run_mediapipe_model(
    python: &Path,
    path: &Path,
    max: Option<usize>,
    model: &str,
) -> MediaPipeRun {
    let (json_path, text_path, keep) = outputs(path, model);
    let was_cached = keep && cached(&json_path, &text_path);
    if !was_cached {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/bench_mediapipe.py");
        let mut cmd = Command::new(python);
        cmd.arg(&script)
            .arg(path)
            .args([model, "1", "--landmarks"])
            .arg(&json_path);
        // A cache holds every frame, so that any bound reads it.
        if let Some(m) = max.filter(|_| !keep) {
            cmd.args(["--max-frames", &m.to_string()]);
        }
        let output = cmd.output().unwrap();
        assert!(
            output.status.success(),
            "MediaPipe on {}: {}",
            path.display(),
            String::from_utf8_lossy(&output.stderr)
        );
        std::fs::write(&text_path, &output.stdout).unwrap();
    }
    let stdout = std::fs::read_to_string(&text_path).unwrap();
    let fps = stdout
        .split_whitespace()
        .find_map(|w| w.strip_prefix("fps_with_decoding="))
        .unwrap()
        .parse()
        .unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    if !keep {
        let _ = std::fs::remove_file(&json_path);
        let _ = std::fs::remove_file(&text_path);
    }
    let size = |k: &str| json[k].as_f64().unwrap_or(0.0) as f32;
    MediaPipeRun {
        frames: points(&json["frames"], max),
        world: points(&json["world"], max),
        width: size("width"),
        height: size("height"),
        fps,
        cached: was_cached,
    }
}
