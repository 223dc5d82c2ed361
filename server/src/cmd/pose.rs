//! `rigcast pose VIDEO [--json] [-o OUT.bvh] [--model lite|full|heavy|full-int8]
//! [--people N] [--finder detector|search] [--decode-side PIXELS] [--threads N] [--max-frames N]`:
//! offline pose extraction from a video file or image sequence, with progress on standard error
//! and a last line with the frame rate (decoding included) and the tracker's counters.
//!
//! `--json` prints exactly one JSON object on standard output:
//! `{"fps", "frames": [{"time_secs", "image", "world", "people"}]}` — `image` is 33 × `[x, y,
//! z, visibility]` in pixels of the input (z in the same pixel scale, smaller = nearer),
//! `world` is 33 × `[x, y, z]` metres, hip-centred, in the camera's axes (x right in the image,
//! y down, z away from the camera); both `null` for frames without person `#0`. `people` holds
//! one `{"image", "world"}` per identity slot (`#0`, `#1`, …; `null`s when that person is not
//! seen). `-o` writes person `#0`'s motion as BVH on the BlazePose source skeleton (frames
//! without them hold the last pose).

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use rigcast_retarget::{Clip, Pose};
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, Finder, FrameSource, Landmarks, ModelKind, PipelineConfig,
    PosePipeline, RgbFrame, TrackerConfig, NUM_LANDMARKS,
};

/// Options of `rigcast pose`.
#[derive(Debug, Args)]
pub struct PoseArgs {
    /// Video file (H.264, VP9, MJPEG, … anything ffmpeg decodes), a directory of images, or a
    /// printf pattern such as `frames/%04d.png`.
    pub video: PathBuf,
    /// Print the landmarks as one JSON object on standard output.
    #[arg(long)]
    pub json: bool,
    /// Write the motion as BVH on the BlazePose source skeleton.
    #[arg(short = 'o', long = "output", value_name = "OUT.bvh")]
    pub output: Option<PathBuf>,
    /// Landmark model: lite, full, heavy, or full-int8 (full quantised to int8 at setup time:
    /// as fast as lite but less accurate than either, 14 % of the torso off full's on average;
    /// see BENCHMARKS.md).
    #[arg(long, default_value = "lite", value_parser = parse_model)]
    pub model: ModelKind,
    /// Frame rate of an image sequence (videos carry their own).
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Stop after this many frames (previews, tests).
    #[arg(long, value_name = "N")]
    pub max_frames: Option<u64>,
    /// Decode with the short side scaled down to this many pixels (0: the video's own size).
    /// Landmarks are reported in pixels of the video either way.
    #[arg(long, value_name = "PIXELS", default_value_t = DEFAULT_DECODE_SIDE)]
    pub decode_side: u32,
    /// Inference threads (ONNX Runtime intra-op).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// People tracked at once.
    #[arg(long, value_name = "N")]
    pub people: Option<usize>,
    /// How people are found: the person detector, or the landmark model over candidate crops.
    #[arg(long, value_parser = parse_finder)]
    pub finder: Option<Finder>,
}

fn parse_finder(s: &str) -> Result<Finder, String> {
    match s {
        "detector" => Ok(Finder::Detector),
        "search" => Ok(Finder::Search),
        other => Err(format!(
            "unknown finder {other:?}: expected detector or search"
        )),
    }
}

/// The default of `--decode-side`, see [`DecodeSize::FOR_MODEL`].
const DEFAULT_DECODE_SIDE: u32 = match DecodeSize::FOR_MODEL {
    DecodeSize::ShortSide(side) => side,
    DecodeSize::Full => 0,
};

fn parse_model(s: &str) -> Result<ModelKind, String> {
    s.parse()
}

/// Runs the extraction.
pub fn run(args: &PoseArgs) -> anyhow::Result<()> {
    if !args.json && args.output.is_none() {
        anyhow::bail!("nothing to do: pass --json and/or -o OUT.bvh");
    }
    let size = match args.decode_side {
        0 => DecodeSize::Full,
        side => DecodeSize::ShortSide(side),
    };
    let mut source = FfmpegSource::open_at(&args.video, size, args.fps)?;
    let fps = source.fps().unwrap_or(args.fps);
    let mut pipeline = PosePipeline::new(&pipeline_config(args)?)?;
    let skeleton = Arc::clone(pipeline.skeleton());
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let poses = track(args, (&mut source, fps), &mut pipeline, &mut out)?;
    let Some(path) = &args.output else {
        return Ok(());
    };
    if poses.is_empty() {
        anyhow::bail!(
            "{}: no frames decoded, nothing to write",
            args.video.display()
        );
    }
    let name = args
        .video
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "pose".into());
    let clip = Clip::new(name, skeleton, poses, 1.0 / fps)?;
    rigcast_sources::save_clip(path, &clip)
        .with_context(|| format!("writing {}", path.display()))?;
    eprintln!("pose: wrote {}", path.display());
    Ok(())
}

/// The pipeline the command line asks for, over the defaults.
fn pipeline_config(args: &PoseArgs) -> anyhow::Result<PipelineConfig> {
    let defaults = PipelineConfig::default();
    let tracker = TrackerConfig {
        max_people: args.people.unwrap_or(defaults.tracker.max_people),
        finder: args.finder.unwrap_or(defaults.tracker.finder),
        ..defaults.tracker
    };
    if tracker.max_people == 0 {
        anyhow::bail!("--people must be at least 1");
    }
    Ok(PipelineConfig {
        model: args.model,
        threads: args.threads.unwrap_or(defaults.threads),
        tracker,
        ..defaults
    })
}

/// Runs `pipeline` over the video (`source` at `fps`), writing the JSON to `out` with
/// `--json`, progress and a summary to standard error. Returns person #0's pose on every
/// frame when a BVH is to be written (the last seen pose where they are not), else nothing.
fn track(
    args: &PoseArgs,
    (source, fps): (&mut FfmpegSource, f64),
    pipeline: &mut PosePipeline,
    out: &mut impl Write,
) -> anyhow::Result<Vec<Pose>> {
    let mut pose = pipeline.skeleton().rest_pose();
    let mut poses: Vec<Pose> = Vec::new();
    if args.json {
        let mut fps_text = String::new();
        push_json_number(&mut fps_text, fps);
        write!(out, "{{\"fps\":{fps_text},\"frames\":[")?;
    }
    let mut frame = RgbFrame::default();
    let mut tally = Tally::new();
    let mut line = String::new();
    while args.max_frames.is_none_or(|max| tally.frames < max) && source.next_frame(&mut frame)? {
        pipeline.process_frame(&frame)?;
        tally.posed();
        let seen = pipeline.person(0).is_some();
        if let (true, Some(p)) = (seen, pipeline.pose(0)) {
            pose.clone_from(p);
        }
        if args.json {
            line.clear();
            frame_json(frame.time_secs, pipeline, &mut line);
            if tally.frames > 0 {
                out.write_all(b",")?;
            }
            out.write_all(line.as_bytes())?;
        }
        if args.output.is_some() {
            poses.push(pose.clone());
        }
        tally.frame(seen, frame.time_secs);
    }
    if args.json {
        out.write_all(b"]}\n")?;
    }
    out.flush()?;
    tally.summary(pipeline);
    Ok(poses)
}

/// Frames tracked so far, for progress lines and the summary.
struct Tally {
    started: Instant,
    frames: u64,
    /// Frames with person #0.
    found: u64,
    /// Time to the first pose: decoder start-up plus the first frame's work (what a performer
    /// waits for before anything moves).
    first_pose_ms: Option<f64>,
}

impl Tally {
    fn new() -> Self {
        Tally {
            started: Instant::now(),
            frames: 0,
            found: 0,
            first_pose_ms: None,
        }
    }

    /// A frame's pose is out.
    fn posed(&mut self) {
        let ms = self.started.elapsed().as_secs_f64() * 1e3;
        self.first_pose_ms.get_or_insert(ms);
    }

    /// Counts a tracked frame (at `time_secs` of the video); a progress line every 30.
    fn frame(&mut self, seen: bool, time_secs: f64) {
        let secs = self.started.elapsed().as_secs_f64();
        self.found += u64::from(seen);
        self.frames += 1;
        if self.frames % 30 == 0 {
            eprintln!(
                "pose: frame {} ({time_secs:.1} s of video), person in {}, {:.1} fps",
                self.frames,
                self.found,
                self.frames as f64 / secs
            );
        }
    }

    fn summary(&self, pipeline: &PosePipeline) {
        let secs = self.started.elapsed().as_secs_f64();
        eprintln!(
            "pose: {} frames, person #0 in {}, {secs:.1} s ({:.1} fps), first pose after {:.0} ms, \
             {:?}",
            self.frames,
            self.found,
            self.frames as f64 / secs.max(1e-9),
            self.first_pose_ms.unwrap_or(0.0),
            pipeline.stats()
        );
    }
}

/// Appends `v` rounded to 5 decimals. JSON has no NaN/infinity; a non-finite value becomes 0
/// (never produced by the model in practice, but the output must stay parseable). Written in
/// place rather than as one string per number: a frame has about 500 numbers per person.
fn push_json_number(out: &mut String, v: f64) {
    use std::fmt::Write as _;
    if v.is_finite() {
        // Writing to a String cannot fail.
        let _ = write!(out, "{}", (v * 1e5).round() / 1e5);
    } else {
        out.push('0');
    }
}

fn frame_json(time_secs: f64, pipeline: &PosePipeline, out: &mut String) {
    out.push_str("{\"time_secs\":");
    push_json_number(out, time_secs);
    out.push(',');
    person_json(pipeline.person(0), out);
    out.push_str(",\"people\":[");
    for slot in 0..pipeline.num_people() {
        if slot > 0 {
            out.push(',');
        }
        out.push('{');
        person_json(pipeline.person(slot), out);
        out.push('}');
    }
    out.push_str("]}");
}

/// `"image":[…],"world":[…]` (or both `null`) for one person.
fn person_json(landmarks: Option<&Landmarks>, out: &mut String) {
    let Some(lm) = landmarks else {
        out.push_str("\"image\":null,\"world\":null");
        return;
    };
    out.push_str("\"image\":");
    json_points(out, &lm.image[..NUM_LANDMARKS]);
    out.push_str(",\"world\":");
    json_points(out, &lm.world[..NUM_LANDMARKS]);
}

/// `[[x,y,…],…]`: each point's coordinates as JSON numbers.
fn json_points<const N: usize, P: AsRef<[f32; N]>>(out: &mut String, points: &[P]) {
    out.push('[');
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push('[');
        for (j, c) in p.as_ref().iter().enumerate() {
            if j > 0 {
                out.push(',');
            }
            push_json_number(out, *c as f64);
        }
        out.push(']');
    }
    out.push(']');
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn person_json_is_valid_with_and_without_a_person() {
        let mut s = String::from("{");
        person_json(None, &mut s);
        s.push('}');
        let v: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert!(v["image"].is_null() && v["world"].is_null());

        let mut lm = Landmarks::default();
        lm.image[32] = glam::Vec4::new(10.0, 20.0, -3.0, 0.9);
        lm.world[0] = glam::Vec3::new(f32::NAN, 0.1, 0.2);
        s = String::from("{");
        person_json(Some(&lm), &mut s);
        s.push('}');
        let v: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert_eq!(v["image"].as_array().unwrap().len(), 33);
        assert_eq!(v["world"].as_array().unwrap().len(), 33);
        assert_eq!(v["image"][32][1], 20.0);
        assert_eq!(v["world"][0][0], 0);
    }
}
