//! Webcam capture through `nokhwa` 0.10 (`input-native`: V4L2 on Linux).
//!
//! Behind the cargo feature `webcam`, on by default (`--no-default-features` builds without
//! it): nokhwa's V4L2 bindings run bindgen at build time, which needs libclang (Debian:
//! `libclang-dev`, installed by `scripts/install-apps.sh`).
//!
//! The mode (size, rate, pixel format) is chosen by [`choose_mode`] from what the driver
//! enumerates ([`list_cameras`]) and opened exactly. A camera that fails mid-stream (unplugged,
//! USB reset) makes [`Webcam::next_frame`] return [`VisionError::CameraLost`]; the next calls
//! try to open it again, at most every [`RETRY`], so the subject comes back when the camera
//! does. Tested against an emulated V4L2 device in `tests/webcam_emulated.rs`.

mod list;

use std::time::{Duration, Instant};

use nokhwa::pixel_format::RgbFormat;
use nokhwa::utils::{
    CameraFormat, CameraIndex, FrameFormat, RequestedFormat, RequestedFormatType, Resolution,
};
use nokhwa::Camera;

pub use list::{describe_cameras, list_cameras, CameraInfo};

use super::camera_modes::{choose_mode, CameraMode, PixelFormat, WebcamOptions};
use super::error::VisionError;
use super::frame::{FrameSource, RgbFrame};

/// Stale frames skipped at most per read (V4L2 drivers queue about four buffers).
const MAX_SKIPPED: u32 = 4;

/// How often a lost camera is looked for again.
pub const RETRY: Duration = Duration::from_millis(500);

/// A webcam yielding RGB frames stamped with the driver's capture time.
pub struct Webcam {
    index: u32,
    options: WebcamOptions,
    camera: Option<Camera>,
    mode: CameraMode,
    name: String,
    started: Instant,
    frames: u64,
    last_attempt: Instant,
}

debug_fields!(Webcam { name, mode });

impl Webcam {
    /// Opens camera `index` in the mode [`choose_mode`] picks for `options`. Errors name the
    /// cameras that exist when `index` is not one of them, and say so when it is busy.
    pub fn open(index: u32, options: WebcamOptions) -> Result<Webcam, VisionError> {
        let (camera, mode, name) = open_camera(index, &options)?;
        Ok(Webcam {
            index,
            options,
            camera: Some(camera),
            mode,
            name,
            started: Instant::now(),
            frames: 0,
            last_attempt: Instant::now(),
        })
    }

    /// The mode the camera was opened in.
    pub fn mode(&self) -> CameraMode {
        self.mode
    }

    /// Looks for the lost camera again (at most every [`RETRY`], sleeping out the rest).
    fn reopen(&mut self) -> Result<(), VisionError> {
        let wait = RETRY.saturating_sub(self.last_attempt.elapsed());
        std::thread::sleep(wait);
        self.last_attempt = Instant::now();
        match open_camera(self.index, &self.options) {
            Ok((camera, mode, name)) => {
                tracing::info!("camera {} is back ({mode})", self.index);
                self.camera = Some(camera);
                self.mode = mode;
                self.name = name;
                Ok(())
            }
            Err(e) => Err(VisionError::CameraLost(format!(
                "camera {} is gone, waiting for it to come back ({e})",
                self.index
            ))),
        }
    }
}

/// Lists the cameras, picks the mode and opens the stream.
fn open_camera(
    index: u32,
    options: &WebcamOptions,
) -> Result<(Camera, CameraMode, String), VisionError> {
    let cameras = list_cameras();
    let Some(info) = cameras.iter().find(|c| c.index == index) else {
        return Err(VisionError::Webcam(format!(
            "no camera {index}; the cameras here are: {}",
            describe_cameras(&cameras)
        )));
    };
    let choice = choose_mode(&info.modes, options)
        .map_err(|e| VisionError::Webcam(format!("camera {index} ({}): {e}", info.name)))?;
    for line in &choice.fallbacks {
        tracing::warn!("camera {index} ({}): {line}", info.name);
    }
    let mode = choice.mode;
    let frame_format = match mode.format {
        PixelFormat::Yuyv => FrameFormat::YUYV,
        PixelFormat::Mjpeg => FrameFormat::MJPEG,
    };
    let exact = CameraFormat::new(
        Resolution::new(mode.width, mode.height),
        frame_format,
        mode.fps,
    );
    let formats = [frame_format];
    let requested = RequestedFormat::with_formats(RequestedFormatType::Exact(exact), &formats);
    let fail = |what: &str, e: nokhwa::NokhwaError| {
        let text = e.to_string();
        if text.contains("busy") || text.contains("os error 16") {
            VisionError::Webcam(format!(
                "camera {index} ({}) is busy: another program is using it ({text})",
                info.name
            ))
        } else {
            VisionError::Webcam(format!(
                "cannot {what} camera {index} ({}) in {mode}: {text}",
                info.name
            ))
        }
    };
    let mut camera =
        Camera::new(CameraIndex::Index(index), requested).map_err(|e| fail("open", e))?;
    camera.open_stream().map_err(|e| fail("start", e))?;
    let name = format!("webcam:{index} ({})", info.name);
    Ok((camera, mode, name))
}

// Safety of Send: nokhwa's Camera is used from one thread at a time (the source's own).
unsafe impl Send for Webcam {}

impl FrameSource for Webcam {
    fn describe(&self) -> &str {
        &self.name
    }
    fn fps(&self) -> Option<f64> {
        Some(self.mode.fps as f64)
    }
    fn size(&self) -> (u32, u32) {
        (self.mode.width, self.mode.height)
    }
    fn camera_mode(&self) -> Option<CameraMode> {
        Some(self.mode)
    }
    fn next_frame(&mut self, out: &mut RgbFrame) -> Result<bool, VisionError> {
        if self.camera.is_none() {
            self.reopen()?;
        }
        let Some(camera) = self.camera.as_mut() else {
            return Err(VisionError::CameraLost(format!(
                "camera {} is gone",
                self.index
            )));
        };
        // The driver hands over its oldest filled buffer: after a slow frame (a model run
        // longer than the frame interval) that one is old. Frames older than 1.5 intervals are
        // skipped, at most one per driver buffer, so the newest frame wins (only dequeues are
        // spent on them, no decoding).
        let stale_after = 1_500_000_000 / u64::from(self.mode.fps.max(1));
        let mut skipped = 0;
        // `frame` copies the driver's mapped buffer into a new one, the one allocation per
        // frame of this path (`tests/webcam_emulated.rs` counts it). It is nokhwa's: its
        // `frame_raw` borrows the mapped buffer but drops the driver's timestamp, which the
        // latency figures are measured from.
        let buffer = loop {
            let b = match camera.frame() {
                Ok(b) => b,
                Err(e) => {
                    // Dropping the camera closes the device so that it can come back.
                    self.camera = None;
                    self.last_attempt = Instant::now();
                    return Err(VisionError::CameraLost(format!(
                        "camera {} stopped: {e}",
                        self.index
                    )));
                }
            };
            let age = b
                .capture_timestamp()
                .and_then(|d| u64::try_from(d.as_nanos()).ok())
                .map_or(0, |t| crate::live::unix_nanos_now().saturating_sub(t));
            if age <= stale_after || skipped >= MAX_SKIPPED {
                break b;
            }
            skipped += 1;
        };
        let dequeued = crate::live::unix_nanos_now();
        let r = buffer.resolution();
        out.resize(r.width(), r.height());
        buffer
            .decode_image_to_buffer::<RgbFormat>(&mut out.data)
            .map_err(|e| VisionError::Webcam(format!("cannot decode frame: {e}")))?;
        // The driver's timestamp (CLOCK_MONOTONIC, mapped to the wall clock by nokhwa) is when
        // the frame was captured; without one, when it was dequeued.
        let captured = buffer
            .capture_timestamp()
            .and_then(|d| u64::try_from(d.as_nanos()).ok())
            .filter(|n| *n > 0 && *n <= dequeued)
            .unwrap_or(dequeued);
        out.clock = super::frame::FrameClock {
            captured_unix_nanos: captured,
            dequeued_unix_nanos: dequeued,
            decoded_unix_nanos: crate::live::unix_nanos_now(),
        };
        out.time_secs = self.started.elapsed().as_secs_f64();
        out.index = self.frames;
        self.frames += 1;
        Ok(true)
    }
}
