//! The webcam source through the real nokhwa -> v4l -> V4L2 code against an emulated camera
//! (`v4l2_emu/v4l2_emu.c`, preloaded into a child run of this test binary) serving real
//! footage (`../shared/data/video`, else the pose2sim clips setup fetched: a clean clone in CI
//! runs these tests too) as YUYV and MJPEG:
//! - format negotiation: asked size and rate met exactly when offered, the nearest otherwise;
//! - both pixel formats decoded right: the first frame the camera serves, decoded by nokhwa,
//!   against ffmpeg's decode of the very same bytes;
//! - the driver's timestamps reach the frame (capture <= dequeue, spaced by the frame interval);
//! - a missing camera is an error naming the cameras that exist; a busy one says it is busy;
//! - in steady state a YUYV frame's only heap allocation is nokhwa's copy of the driver's
//!   buffer (counted with a global allocator on the reading thread).
//!
//! Skipped with a printed reason without gcc, ffmpeg or the footage.
#![cfg(feature = "webcam")]
#![allow(clippy::unwrap_used)]

mod v4l2_emu;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;
use std::process::Command;

use rigcast_sources::vision::{FrameSource, RgbFrame, Webcam, WebcamOptions};
use v4l2_emu::{mode, EmuCamera, Mode};

const CHILD: &str = "RIGCAST_EMU_CHILD";
const YUYV_VGA: Mode = mode("YUYV", 640, 480, 30);
const YUYV_QVGA: Mode = mode("YUYV", 320, 240, 30);
const MJPG_VGA: Mode = mode("MJPG", 640, 480, 60);
const MJPG_720: Mode = mode("MJPG", 1280, 720, 30);
const MODES: [Mode; 4] = [YUYV_VGA, YUYV_QVGA, MJPG_VGA, MJPG_720];
/// Frames decoded per mode (the camera loops them).
const FRAMES: usize = 12;

/// Counts the heap allocations (and their bytes) of the thread that switches it on.
struct CountingAlloc;

thread_local! {
    static COUNT_HERE: Cell<bool> = const { Cell::new(false) };
    static ALLOCATED: Cell<(u64, u64)> = const { Cell::new((0, 0)) };
}

fn count(bytes: usize) {
    if COUNT_HERE.with(Cell::get) {
        ALLOCATED.with(|a| {
            let (n, b) = a.get();
            a.set((n + 1, b + bytes as u64));
        });
    }
}

unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// Frames read before allocations are counted (buffers reach their size).
const WARM_FRAMES: usize = 3;

/// In the child (the shim preloaded): opens camera `index` with the options in the
/// environment, reads `n` frames and writes what it saw to `$OUT` (`$OUT.rgb`: frame 0).
fn child_capture() {
    let out = std::env::var("RIGCAST_EMU_OUT").unwrap();
    let index: u32 = std::env::var("RIGCAST_EMU_INDEX").unwrap().parse().unwrap();
    let opts = WebcamOptions::parse_query(&std::env::var("RIGCAST_EMU_OPTS").unwrap()).unwrap();
    let n: usize = std::env::var("RIGCAST_EMU_FRAMES")
        .unwrap()
        .parse()
        .unwrap();
    let mut report = String::new();
    match Webcam::open(index, opts) {
        Err(e) => report.push_str(&format!("error {e}\n")),
        Ok(mut cam) => {
            report.push_str(&format!("mode {}\n", cam.mode()));
            let mut frame = RgbFrame::default();
            let slow = std::env::var("RIGCAST_EMU_SLOW_MS")
                .ok()
                .and_then(|v| v.parse().ok());
            for k in 0..n {
                if let Some(ms) = slow {
                    // A reader slower than the camera (a long model run).
                    std::thread::sleep(std::time::Duration::from_millis(ms));
                }
                COUNT_HERE.with(|c| c.set(k >= WARM_FRAMES));
                assert!(cam.next_frame(&mut frame).unwrap());
                COUNT_HERE.with(|c| c.set(false));
                if k == 0 {
                    std::fs::write(format!("{out}.rgb"), &frame.data).unwrap();
                }
                let c = frame.clock;
                report.push_str(&format!(
                    "frame {} {}x{} {} {} {}\n",
                    k,
                    frame.width,
                    frame.height,
                    c.captured_unix_nanos,
                    c.dequeued_unix_nanos,
                    c.decoded_unix_nanos
                ));
            }
            let (allocations, bytes) = ALLOCATED.with(Cell::get);
            report.push_str(&format!(
                "allocations {allocations} bytes {bytes} frames {}\n",
                n.saturating_sub(WARM_FRAMES)
            ));
            if std::env::var("RIGCAST_EMU_HOLD").is_ok() {
                // Keep streaming until told to stop (the busy test's first user).
                let stop = format!("{out}.stop");
                std::fs::write(format!("{out}.streaming"), b"").unwrap();
                while !Path::new(&stop).exists() {
                    cam.next_frame(&mut frame).unwrap();
                }
            }
        }
    }
    std::fs::write(&out, report).unwrap();
}

/// Runs `child_capture` in a child of this test binary with the camera's shim preloaded.
fn capture(
    cam: &EmuCamera,
    index: u32,
    opts: &str,
    frames: usize,
    hold: bool,
) -> (String, Vec<u8>, std::process::Child) {
    capture_with(cam, index, opts, frames, hold, &[])
}

fn capture_with(
    cam: &EmuCamera,
    index: u32,
    opts: &str,
    frames: usize,
    hold: bool,
    extra: &[(&str, &str)],
) -> (String, Vec<u8>, std::process::Child) {
    let out = cam.state.join(format!(
        "capture-{}-{}",
        opts.replace(['&', '='], "_"),
        hold
    ));
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.args([
        "--exact",
        "child_entry",
        "--nocapture",
        "--test-threads",
        "1",
    ])
    .env(CHILD, "1")
    .env("RIGCAST_EMU_OUT", &out)
    .env("RIGCAST_EMU_INDEX", index.to_string())
    .env("RIGCAST_EMU_OPTS", opts)
    .env("RIGCAST_EMU_FRAMES", frames.to_string());
    if hold {
        cmd.env("RIGCAST_EMU_HOLD", "1");
    }
    cmd.envs(extra.iter().copied());
    for (k, v) in cam.env() {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().unwrap();
    if hold {
        let streaming = out.with_extension("streaming");
        let start = std::time::Instant::now();
        while !Path::new(&format!("{}.streaming", out.display())).exists() {
            assert!(
                start.elapsed().as_secs() < 60,
                "the first user never streamed"
            );
            if let Some(status) = child.try_wait().unwrap() {
                panic!("the first user exited: {status}");
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let _ = streaming;
        return (String::new(), Vec::new(), child);
    }
    let status = child.wait().unwrap();
    assert!(status.success(), "child capture failed ({opts})");
    let report = std::fs::read_to_string(&out).unwrap();
    let rgb = std::fs::read(format!("{}.rgb", out.display())).unwrap_or_default();
    (report, rgb, child)
}

#[test]
fn child_entry() {
    if std::env::var(CHILD).is_ok() {
        child_capture();
    }
}

fn emulated(index: u32) -> Option<EmuCamera> {
    let video = v4l2_emu::footage().into_iter().next()?;
    v4l2_emu::camera(index, "Emulated Cam", &MODES, &video, FRAMES)
}

#[test]
fn asked_modes_are_met_or_the_nearest_is_chosen() {
    if std::env::var(CHILD).is_ok() {
        return;
    }
    let Some(cam) = emulated(0) else { return };
    for (opts, want) in [
        // Default: 640x480 at the highest rate offered there (MJPEG's 60).
        ("", "640x480@60 MJPG"),
        ("width=1280&height=720&fps=30", "1280x720@30 MJPG"),
        ("width=640&height=480&fps=30", "640x480@30 YUYV"),
        ("width=320&height=240", "320x240@30 YUYV"),
        // Not offered: the nearest size, then the nearest rate there.
        ("width=1920&height=1080&fps=60", "1280x720@30 MJPG"),
        ("width=600&height=400&fps=25", "640x480@30 YUYV"),
        ("format=mjpeg&width=320", "640x480@60 MJPG"),
    ] {
        let (report, _, _) = capture(&cam, 0, opts, 3, false);
        let first = report.lines().next().unwrap_or("");
        assert_eq!(first, format!("mode {want}"), "asked {opts:?}: {report}");
        let (w, h) = want.split('@').next().unwrap().split_once('x').unwrap();
        for line in report.lines().filter(|l| l.starts_with("frame ")) {
            let size = line.split(' ').nth(2).unwrap();
            assert_eq!(size, format!("{w}x{h}"), "{opts:?}: {line}");
        }
    }
    // A format the camera lacks is an error naming what it has.
    let yuyv_only = v4l2_emu::camera(1, "YUYV Only", &[YUYV_VGA], &cam.footage, FRAMES).unwrap();
    let (report, _, _) = capture(&yuyv_only, 1, "format=mjpeg", 1, false);
    assert!(
        report.contains("no MJPG") && report.contains("YUYV"),
        "{report}"
    );
}

/// Mean and 99th percentile of the absolute channel differences of two RGB images.
fn differences(a: &[u8], b: &[u8]) -> (f64, u8) {
    assert_eq!(a.len(), b.len());
    let mut hist = [0usize; 256];
    let mut sum = 0u64;
    for (x, y) in a.iter().zip(b) {
        let d = x.abs_diff(*y);
        hist[d as usize] += 1;
        sum += d as u64;
    }
    let mut seen = 0;
    let p99 = (0..256)
        .find(|d| {
            seen += hist[*d];
            seen * 100 >= a.len() * 99
        })
        .unwrap_or(255) as u8;
    (sum as f64 / a.len() as f64, p99)
}

#[test]
fn both_pixel_formats_decode_like_ffmpeg() {
    if std::env::var(CHILD).is_ok() {
        return;
    }
    // Every clip of the folder would be slow; the first three cover different scenes.
    for video in v4l2_emu::footage().into_iter().take(3) {
        let Some(cam) = v4l2_emu::camera(0, "Emulated Cam", &MODES, &video, FRAMES) else {
            return;
        };
        for (m, opts) in [
            (YUYV_VGA, "width=640&height=480&fps=30&format=yuyv"),
            (MJPG_720, "width=1280&height=720&fps=30&format=mjpeg"),
        ] {
            let (report, rgb, _) = capture(&cam, 0, opts, 1, false);
            assert!(report.starts_with("mode "), "{report}");
            let reference = cam.reference_rgb(m, 0);
            assert_eq!(rgb.len(), (m.width * m.height * 3) as usize, "{report}");
            let (mean, p99) = differences(&rgb, &reference);
            // Colour-conversion rounding and chroma upsampling differ between decoders; a
            // wrong layout (U/V or R/B swapped, a shifted row) costs tens of levels.
            let swapped: Vec<u8> = rgb.chunks(3).flat_map(|p| [p[2], p[1], p[0]]).collect();
            let (swapped_mean, _) = differences(&swapped, &reference);
            println!(
                "{} {}: mean |diff| {mean:.2}, p99 {p99}; with R/B swapped {swapped_mean:.2}",
                video.file_name().unwrap().to_string_lossy(),
                m.fourcc
            );
            assert!(mean <= 2.5 && p99 <= 8, "{m:?}: mean {mean:.2}, p99 {p99}");
            assert!(swapped_mean > mean * 2.0, "the measure cannot tell a swap");
        }
    }
}

#[test]
fn driver_timestamps_reach_the_frames() {
    if std::env::var(CHILD).is_ok() {
        return;
    }
    let Some(cam) = emulated(0) else { return };
    let (report, _, _) = capture(
        &cam,
        0,
        "width=640&height=480&fps=30&format=yuyv",
        20,
        false,
    );
    let times: Vec<(u64, u64)> = report
        .lines()
        .filter(|l| l.starts_with("frame "))
        .map(|l| {
            let f: Vec<u64> = l.split(' ').skip(3).map(|x| x.parse().unwrap()).collect();
            (f[0], f[1])
        })
        .collect();
    assert_eq!(times.len(), 20);
    for (captured, dequeued) in &times {
        assert!(captured <= dequeued, "captured after dequeued: {report}");
    }
    // Consecutive captures 1/30 s apart (the emulated clock), within the mapping's jitter.
    for w in times.windows(2) {
        let gap = w[1].0 as f64 - w[0].0 as f64;
        let frames = (gap / 33_333_333.0).round().max(1.0);
        assert!(
            (gap / frames - 33_333_333.0).abs() < 2e6,
            "gap {gap} ns: {report}"
        );
    }
}

#[test]
fn a_missing_camera_names_the_cameras_there_and_a_busy_one_says_busy() {
    if std::env::var(CHILD).is_ok() {
        return;
    }
    let Some(cam) = emulated(2) else { return };
    let (report, _, _) = capture(&cam, 5, "", 1, false);
    assert!(
        report.contains("no camera 5") && report.contains("2 (Emulated Cam)"),
        "{report}"
    );
    // Camera 2 streamed by another process: a second user is told it is busy.
    let (_, _, mut first) = capture(&cam, 2, "width=1280&height=720&fps=30", 1, true);
    let (report, _, _) = capture(&cam, 2, "width=640&height=480&fps=30", 1, false);
    let stop = cam
        .state
        .join("capture-width_1280_height_720_fps_30-true.stop");
    std::fs::write(stop, b"").unwrap();
    assert!(first.wait().unwrap().success());
    assert!(report.contains("busy"), "{report}");
    // Once the first user is gone, it opens.
    let (report, _, _) = capture(&cam, 2, "width=640&height=480&fps=30", 1, false);
    assert!(report.starts_with("mode 640x480@30"), "{report}");
}

#[test]
fn the_only_allocations_per_frame_are_nokhwas() {
    if std::env::var(CHILD).is_ok() {
        return;
    }
    let Some(cam) = emulated(0) else { return };
    // nokhwa's `Camera::frame` copies the mapped driver buffer into a new one (its
    // `frame_raw` borrows it but drops the driver's timestamp, which glass-to-wire is measured
    // from); decoding YUYV into the reused RGB frame and the rest of our path allocate
    // nothing. MJPEG's count is printed for the record: nokhwa's JPEG decoder allocates too
    // (3 more a frame in this test's runs).
    for (m, opts) in [
        (YUYV_VGA, "width=640&height=480&fps=30&format=yuyv"),
        (MJPG_VGA, "width=640&height=480&fps=60&format=mjpeg"),
    ] {
        let (report, _, _) = capture(&cam, 0, opts, 20, false);
        let line = report
            .lines()
            .find(|l| l.starts_with("allocations "))
            .unwrap_or_else(|| panic!("{report}"));
        let f: Vec<u64> = line
            .split(' ')
            .skip(1)
            .step_by(2)
            .map(|x| x.parse().unwrap())
            .collect();
        let (allocations, bytes, frames) = (f[0], f[1], f[2]);
        println!(
            "{}: {allocations} allocations, {bytes} bytes over {frames} frames",
            m.fourcc
        );
        assert_eq!(frames, 17, "{report}");
        // A frame found stale is skipped for a newer one: one more copy each.
        assert!(allocations >= frames, "{m:?}: {report}");
        if m.fourcc == "YUYV" {
            // Every allocation is a copy of a raw frame, 2 bytes a pixel: none is ours.
            let raw = u64::from(m.width * m.height * 2);
            assert_eq!(bytes, allocations * raw, "{report}");
        }
    }
}

#[test]
fn a_slow_reader_gets_the_newest_frame_not_the_oldest_queued() {
    if std::env::var(CHILD).is_ok() {
        return;
    }
    let Some(cam) = emulated(0) else { return };
    // 200 ms between reads at 30 fps: the driver's four buffers fill with frames up to
    // 130 ms old; the source must skip them (capture -> dequeue within 1.5 intervals + a frame).
    let (report, _, _) = capture_with(
        &cam,
        0,
        "width=640&height=480&fps=30&format=yuyv",
        8,
        false,
        &[("RIGCAST_EMU_SLOW_MS", "200")],
    );
    for line in report.lines().filter(|l| l.starts_with("frame ")).skip(1) {
        let f: Vec<u64> = line
            .split(' ')
            .skip(3)
            .map(|x| x.parse().unwrap())
            .collect();
        let age_ms = (f[1] - f[0]) as f64 / 1e6;
        assert!(
            age_ms < 85.0,
            "a stale frame was served ({age_ms:.1} ms old): {report}"
        );
    }
}
