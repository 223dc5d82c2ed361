//! Video files and image sequences decoded by an `ffmpeg` child process piping raw RGB.
//!
//! Why a child process: ffmpeg (Debian package, installed by `scripts/setup-vision.sh`) decodes
//! every common codec (H.264, VP9, MJPEG, …) and image format, and a pipe keeps its crashes
//! and licences out of our process. `ffprobe` tells the size and rate first; frames are then
//! read as exactly `width × height × 3` bytes each. Timestamps are `index / fps` (constant
//! frame rate, which is what `-f rawvideo` delivers after ffmpeg's own rate handling).
//!
//! [`DecodeSize`] lets ffmpeg scale the picture while it converts to RGB: the landmark model
//! sees a 256-pixel crop, so a 1080×1920 frame carries about four times more pixels than any
//! crop can use, and copying them through the pipe costs as much as decoding. Frames are read
//! ahead on a thread ([`ReadAhead`]) so decoding overlaps inference.

use std::io::Read;
use std::path::Path;
use std::process::{Child, Command, Stdio};

use super::error::VisionError;
use super::frame::{FrameSource, RgbFrame};
use super::read_ahead::{ReadAhead, ReadEnd};

/// Frames decoded ahead of the caller (each one `width × height × 3` bytes of memory).
const READ_AHEAD_FRAMES: usize = 2;

/// The size ffmpeg delivers frames at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DecodeSize {
    /// The video's own size.
    #[default]
    Full,
    /// Scaled down (never up) so that the short side has this many pixels, aspect kept.
    ShortSide(u32),
}

impl DecodeSize {
    /// What the pose pipeline decodes at by default: a person who fills half the frame's
    /// height still gets a crop of about 300 pixels, more than the model's 256.
    pub const FOR_MODEL: DecodeSize = DecodeSize::ShortSide(512);

    /// The decoded size for a `width × height` video: even sides, aspect kept.
    pub fn apply(self, width: u32, height: u32) -> (u32, u32) {
        match self {
            DecodeSize::ShortSide(side) if side > 0 && width.min(height) > side => {
                let k = side as f64 / width.min(height) as f64;
                let even = |v: u32| ((v as f64 * k / 2.0).round() as u32 * 2).max(2);
                (even(width), even(height))
            }
            _ => (width, height),
        }
    }
}

/// ffmpeg's decoding threads (`-threads`; "0" lets ffmpeg choose). On two cores or fewer the
/// decoder shares them with two inference threads: frame-threaded decoding then adds only
/// hand-over work and a frame of latency per extra thread, and one thread gives about 5 %
/// more frames per second through the whole pipeline (BENCHMARKS.md, "Decoder settings").
fn decoder_threads() -> &'static str {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if cores <= 2 {
        "1"
    } else {
        "0"
    }
}

/// swscale flags added when `RIGCAST_DECODE_EXACT_RGB` is set: ffmpeg's exact RGB
/// conversion (every step rounded once, chroma interpolated at full resolution) instead of
/// its default, which differs from it by 1-4 levels a channel. A measuring knob: the
/// tracker's two-person decisions on some clips flip under that difference, so running the
/// footage judge both ways shows which figures are chance (BENCHMARKS.md, identity row).
fn exact_rgb_flags() -> &'static str {
    if std::env::var_os("RIGCAST_DECODE_EXACT_RGB").is_some() {
        "+accurate_rnd+full_chroma_int"
    } else {
        ""
    }
}

/// A small change to the decoded pixels when `RIGCAST_DECODE_NUDGE` names one, beside
/// `RIGCAST_DECODE_EXACT_RGB`: a measuring knob like it. A tracker whose readings hold only on
/// one rounding of the picture gives other figures under each of these, so the footage judge
/// run under several of them shows how much of a figure is chance (BENCHMARKS.md, issue 32):
/// `shift`, the decoded picture one pixel to the left (its last column black); `level`, every
/// channel one level brighter; `deblock`, the decoder skipping H.264's loop filter (other
/// pixels by up to a few levels, where the codec's blocks meet). Returns the decoder's input
/// options and the filters after the scaler (each led by a comma).
fn nudge() -> (&'static [&'static str], &'static str) {
    match std::env::var("RIGCAST_DECODE_NUDGE").as_deref() {
        Ok("shift") => (&[], ",crop=iw-1:ih:1:0,pad=iw+1:ih:0:0"),
        Ok("level") => (&[], ",lutrgb=r=val+1:g=val+1:b=val+1"),
        Ok("deblock") => (&["-skip_loop_filter", "all"], ""),
        _ => (&[], ""),
    }
}

/// Frame rate assumed for image sequences unless told otherwise.
pub const DEFAULT_SEQUENCE_FPS: f64 = 30.0;

/// A video file or image sequence decoded through `ffmpeg`.
pub struct FfmpegSource {
    input: String,
    child: Child,
    frames: ReadAhead,
    width: u32,
    height: u32,
    source_from_frame: f32,
    fps: f64,
    next_index: u64,
}

debug_fields!(FfmpegSource {
    input,
    width,
    height,
    fps
});

/// What `ffprobe` reports about the first video stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VideoInfo {
    /// Displayed width (after rotation metadata).
    pub width: u32,
    /// Displayed height.
    pub height: u32,
    /// Frames per second (0 when unknown).
    pub fps: f64,
}

fn decoder_error(program: &'static str, input: &str, message: impl Into<String>) -> VisionError {
    VisionError::Decoder {
        program,
        input: input.to_string(),
        message: message.into(),
    }
}

fn parse_rate(s: &str) -> Option<f64> {
    let (n, d) = s.split_once('/').unwrap_or((s, "1"));
    let n: f64 = n.trim().parse().ok()?;
    let d: f64 = d.trim().parse().ok()?;
    (d > 0.0 && n > 0.0).then_some(n / d)
}

/// Runs `ffprobe` on `input` (with `pre_args` such as `-f image2`).
pub fn probe(input: &str, pre_args: &[&str]) -> Result<VideoInfo, VisionError> {
    let output = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-select_streams",
            "v:0",
            "-print_format",
            "json",
        ])
        .args(["-show_streams"])
        .args(pre_args)
        .arg(input)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| {
            decoder_error(
                "ffprobe",
                input,
                format!("cannot run ffprobe ({e}); install ffmpeg (`rigcast setup vision`)"),
            )
        })?;
    if !output.status.success() {
        return Err(decoder_error(
            "ffprobe",
            input,
            String::from_utf8_lossy(&output.stderr).trim().to_string(),
        ));
    }
    let json: serde_json::Value = serde_json::from_slice(&output.stdout)
        .map_err(|e| decoder_error("ffprobe", input, format!("unreadable output: {e}")))?;
    let stream = json
        .get("streams")
        .and_then(|s| s.get(0))
        .ok_or_else(|| decoder_error("ffprobe", input, "no video stream"))?;
    let dim = |k: &str| stream.get(k).and_then(|v| v.as_u64()).unwrap_or(0) as u32;
    let (mut width, mut height) = (dim("width"), dim("height"));
    if width == 0 || height == 0 {
        return Err(decoder_error(
            "ffprobe",
            input,
            "video stream without a size",
        ));
    }
    // ffmpeg applies rotation metadata when decoding, so a quarter turn swaps the sides.
    let rotation = stream
        .get("side_data_list")
        .and_then(|l| l.as_array())
        .and_then(|l| l.iter().find_map(|d| d.get("rotation")?.as_f64()))
        .or_else(|| {
            stream
                .get("tags")
                .and_then(|t| t.get("rotate"))
                .and_then(|r| r.as_str())
                .and_then(|r| r.parse().ok())
        })
        .unwrap_or(0.0);
    if ((rotation.abs() / 90.0).round() as i64) % 2 == 1 {
        std::mem::swap(&mut width, &mut height);
    }
    let rate = |k: &str| stream.get(k).and_then(|v| v.as_str()).and_then(parse_rate);
    let fps = rate("avg_frame_rate")
        .or_else(|| rate("r_frame_rate"))
        .unwrap_or(0.0);
    Ok(VideoInfo { width, height, fps })
}

impl FfmpegSource {
    /// Opens a video file (any codec ffmpeg decodes) at its own size.
    pub fn open_video(path: &Path) -> Result<FfmpegSource, VisionError> {
        Self::open_video_at(path, DecodeSize::Full)
    }

    /// Opens a video file, decoded at `size`.
    pub fn open_video_at(path: &Path, size: DecodeSize) -> Result<FfmpegSource, VisionError> {
        if !path.exists() {
            return Err(VisionError::NoInput {
                path: path.to_path_buf(),
            });
        }
        let input = path.to_string_lossy().into_owned();
        let info = probe(&input, &[])?;
        let fps = if info.fps > 0.0 {
            info.fps
        } else {
            DEFAULT_SEQUENCE_FPS
        };
        Self::spawn(input, &[], info, fps, size)
    }

    /// Opens an image sequence: either a directory (every `.png`/`.jpg`/`.jpeg` in name order)
    /// or a printf pattern such as `frames/img_%04d.png`.
    pub fn open_sequence(pattern: &Path, fps: f64) -> Result<FfmpegSource, VisionError> {
        Self::open_sequence_at(pattern, fps, DecodeSize::Full)
    }

    /// [`Self::open_sequence`], decoded at `size`.
    pub fn open_sequence_at(
        pattern: &Path,
        fps: f64,
        size: DecodeSize,
    ) -> Result<FfmpegSource, VisionError> {
        let fps = if fps > 0.0 { fps } else { DEFAULT_SEQUENCE_FPS };
        let rate = format!("{fps}");
        if pattern.is_dir() {
            let ext = sequence_extension(pattern)?;
            let glob = pattern.join(format!("*.{ext}"));
            let input = glob.to_string_lossy().into_owned();
            let pre = [
                "-f",
                "image2",
                "-pattern_type",
                "glob",
                "-framerate",
                rate.as_str(),
            ];
            let info = probe(&input, &pre)?;
            return Self::spawn(input, &pre, info, fps, size);
        }
        let input = pattern.to_string_lossy().into_owned();
        let pre = ["-f", "image2", "-framerate", rate.as_str()];
        let info = probe(&input, &pre)?;
        Self::spawn(input, &pre, info, fps, size)
    }

    /// Opens whatever `path` is: a directory or a `%` pattern is an image sequence, anything
    /// else a video file. Decoded at its own size.
    pub fn open(path: &Path) -> Result<FfmpegSource, VisionError> {
        Self::open_at(path, DecodeSize::Full, DEFAULT_SEQUENCE_FPS)
    }

    /// [`Self::open`] decoded at `size`; `sequence_fps` is the rate of an image sequence.
    pub fn open_at(
        path: &Path,
        size: DecodeSize,
        sequence_fps: f64,
    ) -> Result<FfmpegSource, VisionError> {
        if path.is_dir() || path.to_string_lossy().contains('%') {
            Self::open_sequence_at(path, sequence_fps, size)
        } else {
            Self::open_video_at(path, size)
        }
    }

    fn spawn(
        input: String,
        pre_args: &[&str],
        info: VideoInfo,
        fps: f64,
        size: DecodeSize,
    ) -> Result<FfmpegSource, VisionError> {
        let (width, height) = size.apply(info.width, info.height);
        let exact = exact_rgb_flags();
        let (nudge_input, nudge_filters) = nudge();
        let mut command = Command::new("ffmpeg");
        command
            .args(["-nostdin", "-v", "error"])
            .args(pre_args)
            .args(["-threads", decoder_threads()])
            .args(nudge_input)
            .arg("-i")
            .arg(&input)
            .args(["-map", "0:v:0"]);
        if (width, height) != (info.width, info.height) {
            // Scaling and the RGB conversion happen in one swscale pass. `fast_bilinear` (two
            // taps) costs about 0.75 of `bilinear` (which widens its taps by the scale factor):
            // the crop the model sees is itself a two-tap bilinear resample of this frame, and
            // the landmarks move no more between the two than between `bilinear` and `area`
            // or the video's own size (BENCHMARKS.md, "Decoder settings").
            command.arg("-vf").arg(format!(
                "scale={width}:{height}:flags=fast_bilinear{exact}{nudge_filters}"
            ));
        } else {
            if !exact.is_empty() {
                // The conversion alone, in the scaler ffmpeg inserts with its default flags.
                command.args(["-sws_flags", &format!("bicubic{exact}")]);
            }
            if !nudge_filters.is_empty() {
                // In RGB: a pixel's shift in 4:2:0 would leave an odd width.
                command.args(["-vf", &format!("format=rgb24{nudge_filters}")]);
            }
        }
        let mut child = command
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                decoder_error(
                    "ffmpeg",
                    &input,
                    format!("cannot run ffmpeg ({e}); install it (`rigcast setup vision`)"),
                )
            })?;
        let stdout = child
            .stdout
            .take()
            .ok_or_else(|| decoder_error("ffmpeg", &input, "no stdout pipe"))?;
        let frame_bytes = width as usize * height as usize * 3;
        let frames = ReadAhead::spawn(stdout, frame_bytes, READ_AHEAD_FRAMES)
            .map_err(|e| decoder_error("ffmpeg", &input, format!("reader thread: {e}")))?;
        Ok(FfmpegSource {
            input,
            child,
            frames,
            width,
            height,
            source_from_frame: info.width as f32 / width as f32,
            fps,
            next_index: 0,
        })
    }

    fn stderr_text(&mut self) -> String {
        let mut text = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            // Best effort: at worst the error message is incomplete.
            let _ = e.read_to_string(&mut text);
        }
        text.trim().to_string()
    }
}

fn sequence_extension(dir: &Path) -> Result<&'static str, VisionError> {
    let entries = std::fs::read_dir(dir).map_err(|e| VisionError::Decoder {
        program: "ffmpeg",
        input: dir.display().to_string(),
        message: e.to_string(),
    })?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().to_ascii_lowercase();
        for ext in ["png", "jpg", "jpeg", "bmp"] {
            if name.ends_with(&format!(".{ext}")) {
                return Ok(ext);
            }
        }
    }
    Err(VisionError::Decoder {
        program: "ffmpeg",
        input: dir.display().to_string(),
        message: "directory holds no .png/.jpg/.jpeg/.bmp images".into(),
    })
}

impl FrameSource for FfmpegSource {
    fn describe(&self) -> &str {
        &self.input
    }
    fn fps(&self) -> Option<f64> {
        Some(self.fps)
    }
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    fn next_frame(&mut self, out: &mut RgbFrame) -> Result<bool, VisionError> {
        match self.frames.next_into(&mut out.data) {
            Ok(()) => {}
            Err(ReadEnd::End) => {
                let status = self.child.wait().ok();
                if status.is_some_and(|s| !s.success()) {
                    let msg = self.stderr_text();
                    return Err(decoder_error("ffmpeg", &self.input, msg));
                }
                return Ok(false);
            }
            Err(ReadEnd::Truncated(filled)) => {
                let msg = self.stderr_text();
                let expected = self.frames.frame_bytes();
                return Err(decoder_error(
                    "ffmpeg",
                    &self.input,
                    format!(
                        "frame {} truncated: got {filled} of {expected} bytes {msg}",
                        self.next_index
                    ),
                ));
            }
            Err(ReadEnd::Failed(e)) => return Err(decoder_error("ffmpeg", &self.input, e)),
        }
        out.width = self.width;
        out.height = self.height;
        out.source_from_frame = self.source_from_frame;
        out.index = self.next_index;
        out.time_secs = self.next_index as f64 / self.fps;
        self.next_index += 1;
        Ok(true)
    }
}

impl Drop for FfmpegSource {
    fn drop(&mut self) {
        // A reader that stops early must not leave ffmpeg blocked on a full pipe. Killing it
        // also ends the read-ahead thread (its pipe reaches the end).
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_side_scaling_keeps_aspect_and_never_upscales() {
        assert_eq!(DecodeSize::ShortSide(540).apply(1080, 1920), (540, 960));
        assert_eq!(DecodeSize::ShortSide(512).apply(1088, 1920), (512, 904));
        assert_eq!(DecodeSize::ShortSide(720).apply(640, 480), (640, 480));
        assert_eq!(DecodeSize::Full.apply(1768, 994), (1768, 994));
        assert_eq!(DecodeSize::ShortSide(0).apply(100, 50), (100, 50));
    }
}
