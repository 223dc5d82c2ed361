//! The emulated V4L2 camera of the tests (`v4l2_emu.c`, preloaded): builds the shim with gcc,
//! decodes real footage ([`footage`]) with ffmpeg into the camera's modes (raw
//! YUYV and MJPEG frames) and writes its configuration. Included by path from the tests of
//! `sources` and `server`. Everything is skipped with a printed reason when gcc, ffmpeg or the
//! footage is missing.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// A camera mode to emulate: the four-character code, size and rate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mode {
    pub fourcc: &'static str,
    pub width: u32,
    pub height: u32,
    pub fps: u32,
}

pub const fn mode(fourcc: &'static str, width: u32, height: u32, fps: u32) -> Mode {
    Mode {
        fourcc,
        width,
        height,
        fps,
    }
}

/// One emulated camera, ready to be used by a process started with [`EmuCamera::env`].
#[derive(Debug)]
pub struct EmuCamera {
    pub index: u32,
    pub name: String,
    /// STATE_DIR of the shim: `unplugged` and `busy.lock` live here.
    pub state: PathBuf,
    pub config: PathBuf,
    pub shim: PathBuf,
    pub footage: PathBuf,
    /// Where each mode's frames are (`raw.yuyv` file or MJPEG folder) by (fourcc, w, h).
    pub frames: Vec<(Mode, PathBuf)>,
}

fn work_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("v4l2_emu")
}

fn have(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
        || Command::new(program)
            .arg("-version")
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
}

/// The shim, compiled once per source text (keyed by its length and a checksum).
pub fn build_shim() -> Option<PathBuf> {
    if !have("gcc") {
        println!("SKIP: gcc not found (scripts/install-build-deps.sh installs it)");
        return None;
    }
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../sources/tests/v4l2_emu/v4l2_emu.c");
    let text = std::fs::read(&src).expect("the shim's source");
    let sum = text.iter().fold(0xcbf29ce484222325u64, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x100000001b3)
    });
    let out = work_dir().join(format!("v4l2_emu-{sum:016x}.so"));
    if out.exists() {
        return Some(out);
    }
    std::fs::create_dir_all(work_dir()).expect("work dir");
    // Tests of one binary build it at the same time: each writes its own file.
    let tmp = out.with_extension(format!("{}-{}.tmp", std::process::id(), unique()));
    let status = Command::new("gcc")
        .args([
            "-O2",
            "-Wall",
            "-Wno-format-truncation",
            "-shared",
            "-fPIC",
            "-o",
        ])
        .arg(&tmp)
        .arg(&src)
        .args(["-ldl", "-lpthread"])
        .status()
        .expect("run gcc");
    assert!(status.success(), "gcc failed on {}", src.display());
    std::fs::rename(&tmp, &out).expect("place the shim");
    Some(out)
}

/// Real footage with people, sorted by name: the video files of the shared data's `video`
/// folder (`$RIGCAST_SHARED_DATA`, else `../shared/data` beside the workspace), else, on a
/// machine without it (a clean clone in CI), the pose2sim clips `scripts/setup-vision.sh`
/// fetched beside the vision models.
pub fn footage() -> Vec<PathBuf> {
    let shared = match std::env::var_os("RIGCAST_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    }
    .join("video");
    let fetched = rigcast_sources::vision::VisionAssets::from_env()
        .root
        .join("pose2sim");
    let mut files = videos_in(&shared);
    if files.is_empty() {
        files = videos_in(&fetched);
    }
    if files.is_empty() {
        println!(
            "SKIP: no footage in {} nor {} (scripts/setup-vision.sh fetches the latter)",
            shared.display(),
            fetched.display()
        );
    }
    files
}

/// The video files in `dir`, sorted by name.
fn videos_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| {
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        matches!(ext, "mp4" | "avi" | "mkv" | "mov" | "webm")
    });
    files.sort();
    files
}

/// Decodes `frames` frames of `video` (from `start_secs`) fitted into `m` with ffmpeg.
fn decode(video: &Path, m: Mode, start_secs: f64, frames: usize, out: &Path) {
    // Fitted, not stretched (a portrait clip is pillarboxed): people keep their proportions.
    let (w, h) = (m.width, m.height);
    let scale = format!(
        "scale={w}:{h}:force_original_aspect_ratio=decrease,pad={w}:{h}:(ow-iw)/2:(oh-ih)/2,setsar=1"
    );
    let mut cmd = Command::new("ffmpeg");
    cmd.args(["-v", "error", "-y", "-ss"])
        .arg(format!("{start_secs}"))
        .arg("-i")
        .arg(video)
        .args(["-frames:v", &frames.to_string(), "-vf", &scale, "-an"]);
    if m.fourcc == "YUYV" {
        cmd.args(["-f", "rawvideo", "-pix_fmt", "yuyv422"]).arg(out);
    } else {
        std::fs::create_dir_all(out).expect("mjpeg dir");
        cmd.args([
            "-f", "image2", "-c:v", "mjpeg", "-pix_fmt", "yuvj422p", "-q:v", "3",
        ])
        .arg(out.join("%05d.jpg"));
    }
    let o = cmd.output().expect("run ffmpeg");
    assert!(
        o.status.success(),
        "ffmpeg on {}: {}",
        video.display(),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Camera `index` named `name` offering `modes`, fed `frames` frames of `video`. Returns None
/// (printed reason) when gcc or ffmpeg is missing.
pub fn camera(
    index: u32,
    name: &str,
    modes: &[Mode],
    video: &Path,
    frames: usize,
) -> Option<EmuCamera> {
    let shim = build_shim()?;
    if !have("ffmpeg") {
        println!("SKIP: ffmpeg not found (scripts/setup-vision.sh installs it)");
        return None;
    }
    let stem = video.file_stem().and_then(|s| s.to_str()).unwrap_or("clip");
    let base = work_dir().join(format!("{stem}-{frames}"));
    let state = work_dir().join(format!("state-{}-{index}-{}", std::process::id(), unique()));
    std::fs::create_dir_all(&state).expect("state dir");
    let mut lines = format!("device {index} {} {name}\n", state.display());
    let mut made = Vec::new();
    for m in modes {
        let path = base
            .join(format!("{}x{}", m.width, m.height))
            .join(if m.fourcc == "YUYV" {
                "raw.yuyv"
            } else {
                "mjpeg"
            });
        let ready = path.with_extension("ready");
        if !ready.exists() {
            std::fs::create_dir_all(path.parent().expect("parent")).expect("frames dir");
            decode(video, *m, 1.0, frames, &path);
            std::fs::write(&ready, b"").expect("mark ready");
        }
        lines.push_str(&format!(
            "mode {} {} {} {} {}\n",
            m.fourcc,
            m.width,
            m.height,
            m.fps,
            path.display()
        ));
        made.push((*m, path));
    }
    let config = state.join("cameras.conf");
    std::fs::write(&config, lines).expect("write the config");
    Some(EmuCamera {
        index,
        name: name.into(),
        state,
        config,
        shim,
        footage: video.to_path_buf(),
        frames: made,
    })
}

fn unique() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    N.fetch_add(1, Ordering::Relaxed)
}

impl EmuCamera {
    /// The environment a process needs to see this camera.
    pub fn env(&self) -> Vec<(&'static str, PathBuf)> {
        vec![
            ("LD_PRELOAD", self.shim.clone()),
            ("RIGCAST_V4L2_EMU", self.config.clone()),
        ]
    }

    /// Unplugs the camera (it leaves /dev; open descriptors fail with ENODEV).
    pub fn unplug(&self) {
        std::fs::write(self.state.join("unplugged"), b"").expect("unplug");
    }

    /// Plugs it back in.
    pub fn replug(&self) {
        let _ = std::fs::remove_file(self.state.join("unplugged"));
    }

    /// Frame `k` of `mode` as RGB, decoded by ffmpeg from the very bytes the camera serves.
    pub fn reference_rgb(&self, m: Mode, k: usize) -> Vec<u8> {
        let (_, path) = self
            .frames
            .iter()
            .find(|(x, _)| *x == m)
            .expect("mode emulated");
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-v", "error"]);
        if m.fourcc == "YUYV" {
            let size = format!("{}x{}", m.width, m.height);
            cmd.args(["-f", "rawvideo", "-pix_fmt", "yuyv422", "-s", &size, "-i"])
                .arg(path)
                .args(["-vf", &format!("select=eq(n\\,{k})")]);
        } else {
            cmd.arg("-i").arg(path.join(format!("{:05}.jpg", k + 1)));
        }
        cmd.args(["-frames:v", "1", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"]);
        let o = cmd.output().expect("run ffmpeg");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o.stdout
    }
}

impl Drop for EmuCamera {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.state);
    }
}
