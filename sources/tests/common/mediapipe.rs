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
    /// CPU time a frame with decoding, and of it the decoder's, ms (see [`cpu_ms`]).
    pub cpu_ms: Option<f64>,
    pub decoder_ms: Option<f64>,
    /// Read back from `RIGCAST_MEDIAPIPE_CACHE` (its frame rate is from another run).
    pub cached: bool,
}

/// The CPU time a timed frame in `bench_mediapipe.py`'s summary line `stdout`, ms: its Python
/// process's after the warm-up frame plus its ffmpeg decoder's whole (`what`: `cpu`), or the
/// decoder's alone (`decoder_cpu`). `None` in a line written before the script printed it (a
/// cache from then).
fn cpu_ms(stdout: &str, what: &str) -> Option<f64> {
    let name = format!("{what}_ms_per_frame=");
    stdout
        .split_whitespace()
        .find_map(|w| w.strip_prefix(name.as_str()))
        .and_then(|v| v.parse().ok())
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

/// MediaPipe asked for several people: the Tasks API's `PoseLandmarker` with `num_poses`
/// (see `scripts/bench_mediapipe.py`), MediaPipe's own way to follow several people.
pub struct MediaPipeCrowd {
    /// People asked for.
    pub asked: usize,
    /// Timed frames (the warm-up frame left out) by how many people were found in them, 0 to
    /// `asked`.
    pub found: Vec<usize>,
    /// Frames a second with decoding.
    pub fps: f64,
    /// CPU time a frame with decoding, and of it the decoder's, ms (see [`cpu_ms`]).
    pub cpu_ms: Option<f64>,
    pub decoder_ms: Option<f64>,
    /// Read back from `RIGCAST_MEDIAPIPE_CACHE` (its frame rate is from another run).
    pub cached: bool,
}

impl MediaPipeCrowd {
    /// How many people the clip holds by this run: the most people found together in at least
    /// half the frames (at least 1: a clip where MediaPipe finds nobody is judged against its
    /// one-person tracker, and at most `asked`).
    pub fn people(&self) -> usize {
        let frames: usize = self.found.iter().sum();
        (2..=self.asked)
            .take_while(|&k| 2 * self.found[k..].iter().sum::<usize>() >= frames.max(1))
            .last()
            .unwrap_or(1)
    }

    /// The share of frames where all those asked for were found, in percent.
    pub fn all_found_percent(&self) -> f64 {
        let frames: usize = self.found.iter().sum();
        100.0 * self.found.last().copied().unwrap_or(0) as f64 / frames.max(1) as f64
    }
}

/// MediaPipe asked for `people` (2 or more) over `path`'s first `max` frames, with its `model`:
/// in this run, or read back from `RIGCAST_MEDIAPIPE_CACHE` (`CLIP[.lite].peopleN.FRAMES.txt`).
pub fn run_mediapipe_crowd(
    python: &Path,
    path: &Path,
    max: Option<usize>,
    model: &str,
    people: usize,
) -> MediaPipeCrowd {
    assert!(people >= 2, "the one-person tracker is run_mediapipe's");
    let (_, text_path, keep) = outputs(path, model);
    // Counts cannot be cut to fewer frames afterwards: a cache keeps one run per bound.
    let frames = max.map_or("all".into(), |m| m.to_string());
    let text_path = text_path.with_extension(format!("people{people}.{frames}.txt"));
    let was_cached = keep && text_path.is_file();
    if !was_cached {
        let mut cmd = bench_script(python, path);
        cmd.args([model, &people.to_string()]);
        if let Some(m) = max {
            cmd.args(["--max-frames", &m.to_string()]);
        }
        run_into(cmd, &format!("MediaPipe for {people}"), path, &text_path);
    }
    let stdout = std::fs::read_to_string(&text_path).unwrap();
    if !keep {
        let _ = std::fs::remove_file(&text_path);
    }
    let field = |name: &str| {
        stdout
            .split_whitespace()
            .find_map(|w| w.strip_prefix(name))
            .unwrap_or_else(|| panic!("MediaPipe for {people}: no {name} in {stdout:?}"))
    };
    let found: Vec<usize> = field("found=")
        .split(',')
        .map(|n| n.parse().unwrap())
        .collect();
    assert_eq!(
        found.len(),
        people + 1,
        "MediaPipe for {people}: {stdout:?}"
    );
    MediaPipeCrowd {
        asked: people,
        found,
        fps: field("fps_with_decoding=").parse().unwrap(),
        cpu_ms: cpu_ms(&stdout, "cpu"),
        decoder_ms: cpu_ms(&stdout, "decoder_cpu"),
        cached: was_cached,
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

/// `scripts/bench_mediapipe.py VIDEO` under the venv's python; the caller adds the rest.
fn bench_script(python: &Path, video: &Path) -> Command {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/bench_mediapipe.py");
    let mut cmd = Command::new(python);
    cmd.arg(script).arg(video);
    cmd
}

/// Runs `cmd` and writes its output line to `text_path`; a failure panics with its stderr.
fn run_into(mut cmd: Command, what: &str, video: &Path, text_path: &Path) {
    let output = cmd.output().unwrap();
    assert!(
        output.status.success(),
        "{what} on {}: {}",
        video.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    std::fs::write(text_path, &output.stdout).unwrap();
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
        let mut cmd = bench_script(python, path);
        cmd.args([model, "1", "--landmarks"]).arg(&json_path);
        // A cache holds every frame, so that any bound reads it.
        if let Some(m) = max.filter(|_| !keep) {
            cmd.args(["--max-frames", &m.to_string()]);
        }
        run_into(cmd, "MediaPipe", path, &text_path);
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
        cpu_ms: cpu_ms(&stdout, "cpu"),
        decoder_ms: cpu_ms(&stdout, "decoder_cpu"),
        cached: was_cached,
    }
}
