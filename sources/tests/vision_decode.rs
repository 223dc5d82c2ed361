//! Frame input through ffmpeg: H.264 (the pose2sim footage), VP9, MJPEG and image sequences
//! decode to the same pictures; bad input gives clear errors. The VP9/MJPEG/PNG inputs are
//! made from the H.264 footage with ffmpeg itself, scaled down to keep the test quick.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::path::Path;
use std::process::Command;

use common::{assets_or_skip, mean_abs_diff};
use rigcast_sources::vision::{FfmpegSource, FrameSource, RgbFrame, VisionError};

fn ffmpeg(args: &[&str]) {
    let status = Command::new("ffmpeg")
        .args(["-nostdin", "-v", "error", "-y"])
        .args(args)
        .status()
        .expect("ffmpeg runs (installed by scripts/setup-vision.sh)");
    assert!(status.success(), "ffmpeg {args:?} failed");
}

fn decode_all(mut source: FfmpegSource) -> Vec<RgbFrame> {
    let mut frames = Vec::new();
    let mut f = RgbFrame::default();
    while source.next_frame(&mut f).unwrap() {
        frames.push(f.clone());
    }
    frames
}

#[test]
fn h264_footage_decodes_with_size_rate_and_timestamps() {
    let Some(assets) = assets_or_skip("h264 decode") else {
        return;
    };
    let source = FfmpegSource::open(&assets.pose2sim_video(1)).unwrap();
    assert_eq!(source.size(), (1080, 1920));
    assert_eq!(source.fps(), Some(60.0));
    let frames = decode_all(source);
    assert_eq!(frames.len(), 100);
    assert_eq!(frames[30].index, 30);
    assert!((frames[30].time_secs - 0.5).abs() < 1e-9);
    // Real content, not a black or constant frame.
    let f = &frames[0];
    let mean = f.data.iter().map(|&v| v as f64).sum::<f64>() / f.data.len() as f64;
    assert!(mean > 20.0 && mean < 235.0, "mean {mean}");
}

#[test]
fn vp9_mjpeg_and_image_sequences_match_the_same_frames() {
    let Some(assets) = assets_or_skip("codec decode") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("rigcast-vision-decode-{}", std::process::id()));
    let seq = dir.join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    let src = assets.pose2sim_video(1);
    let src = src.to_str().unwrap();
    let png = seq.join("f_%03d.png");
    // 12 frames at 270×480, lossless PNG: the reference pictures.
    ffmpeg(&[
        "-i",
        src,
        "-frames:v",
        "12",
        "-vf",
        "scale=270:480",
        png.to_str().unwrap(),
    ]);
    let webm = dir.join("clip.webm");
    let avi = dir.join("clip.avi");
    let png_in = png.to_str().unwrap();
    // The 60 fps PNG sequence encoded with `codec` (and its options) into `out`.
    let encode = |codec: &[&str], out: &Path| {
        let input = ["-framerate", "60", "-i", png_in, "-c:v"];
        ffmpeg(&[&input[..], codec, &[out.to_str().unwrap()]].concat());
    };
    encode(
        &[
            "libvpx-vp9",
            "-b:v",
            "0",
            "-crf",
            "20",
            "-deadline",
            "realtime",
            "-cpu-used",
            "8",
        ],
        &webm,
    );
    encode(&["mjpeg", "-q:v", "2"], &avi);

    let reference = decode_all(FfmpegSource::open_sequence(&png, 60.0).unwrap());
    assert_eq!(reference.len(), 12);
    assert_eq!((reference[0].width, reference[0].height), (270, 480));
    // A directory of images is a sequence too.
    let from_dir = decode_all(FfmpegSource::open(&seq).unwrap());
    assert_eq!(from_dir.len(), 12);
    assert_eq!(from_dir[5].data, reference[5].data);

    for (name, path) in [("vp9", &webm), ("mjpeg", &avi)] {
        let frames = decode_all(FfmpegSource::open(path).unwrap());
        assert_eq!(frames.len(), 12, "{name}");
        for i in [0, 6, 11] {
            let d = mean_abs_diff(&frames[i], &reference[i]);
            assert!(d < 6.0, "{name} frame {i}: mean difference {d}");
        }
        // Different frames really differ (the comparison above can fail).
        assert!(
            mean_abs_diff(&frames[0], &reference[11]) > mean_abs_diff(&frames[0], &reference[0])
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_and_bogus_inputs_are_clear_errors() {
    let err = FfmpegSource::open(Path::new("/nonexistent/video.mp4")).unwrap_err();
    assert!(matches!(err, VisionError::NoInput { .. }), "{err}");
    assert!(err.to_string().contains("/nonexistent/video.mp4"));

    if Command::new("ffprobe").arg("-version").output().is_err() {
        eprintln!("SKIP bogus-video part: ffprobe not installed (run scripts/setup-vision.sh)");
        return;
    }
    let path = std::env::temp_dir().join(format!("rigcast-bogus-{}.mp4", std::process::id()));
    std::fs::write(&path, b"this is not a video").unwrap();
    let err = FfmpegSource::open(&path).unwrap_err();
    assert!(
        matches!(
            err,
            VisionError::Decoder {
                program: "ffprobe",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("rigcast-bogus"), "{err}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn missing_setup_is_reported_with_the_command_to_run() {
    use rigcast_sources::vision::{PipelineConfig, PosePipeline, VisionAssets};
    let config = PipelineConfig {
        assets: VisionAssets::at("/nonexistent/rigcast-home/vision"),
        ..PipelineConfig::default()
    };
    let err = PosePipeline::new(&config).unwrap_err();
    assert!(matches!(err, VisionError::NotSetUp { .. }), "{err}");
    assert!(err.to_string().contains("rigcast setup vision"), "{err}");
}

#[test]
fn webcam_without_camera_or_support_is_an_error_not_a_panic() {
    // Either this build lacks the `webcam` feature or there is no camera here: both must be
    // a clear error.
    match rigcast_sources::vision::open_webcam(0, Default::default()) {
        Err(VisionError::Webcam(msg)) => assert!(!msg.is_empty()),
        Err(other) => panic!("unexpected error kind: {other}"),
        Ok(_) => eprintln!("a camera is attached; nothing to check"),
    }
}
