//! Webcam capture through `nokhwa` 0.10 (`input-native`: V4L2 on Linux).
//!
//! Behind the cargo feature `webcam`, off by default: nokhwa's V4L2 bindings run bindgen at
//! build time, which needs libclang (Debian: `apt-get install -y libclang-dev`). Build with
//! `cargo build -p rigcast-sources --features webcam` (the server binary does not forward the
//! feature yet). Without the feature, [`super::open_webcam`] returns an error saying so. With no camera, [`Webcam::open`] returns [`VisionError::Webcam`] naming the
//! problem (tested in `tests/vision_webcam.rs`), never panics.

use std::time::Instant;

use nokhwa::pixel_format::RgbFormat;
use nokhwa::utils::{CameraIndex, RequestedFormat, RequestedFormatType};
use nokhwa::Camera;

use super::error::VisionError;
use super::frame::{FrameSource, RgbFrame};

/// A webcam yielding RGB frames stamped with the time since opening.
pub struct Webcam {
    camera: Camera,
    name: String,
    started: Instant,
    index: u64,
}

debug_fields!(Webcam { name });

impl Webcam {
    /// Opens camera number `index` at its highest frame rate.
    pub fn open(index: u32) -> Result<Webcam, VisionError> {
        let cameras = nokhwa::query(nokhwa::utils::ApiBackend::Auto)
            .map_err(|e| VisionError::Webcam(format!("cannot list cameras: {e}")))?;
        if cameras.is_empty() {
            return Err(VisionError::Webcam(format!(
                "no camera found (asked for camera {index}; is a /dev/video* device present \
                 and readable?)"
            )));
        }
        let format =
            RequestedFormat::new::<RgbFormat>(RequestedFormatType::AbsoluteHighestFrameRate);
        let mut camera = Camera::new(CameraIndex::Index(index), format)
            .map_err(|e| VisionError::Webcam(format!("cannot open camera {index}: {e}")))?;
        camera
            .open_stream()
            .map_err(|e| VisionError::Webcam(format!("cannot start camera {index}: {e}")))?;
        let name = format!("webcam:{index} ({})", camera.info().human_name());
        Ok(Webcam {
            camera,
            name,
            started: Instant::now(),
            index: 0,
        })
    }
}

// Safety of Send: nokhwa's Camera is used from one thread at a time (the source's own).
unsafe impl Send for Webcam {}

impl FrameSource for Webcam {
    fn describe(&self) -> &str {
        &self.name
    }
    fn fps(&self) -> Option<f64> {
        Some(self.camera.frame_rate() as f64)
    }
    fn size(&self) -> (u32, u32) {
        let r = self.camera.resolution();
        (r.width(), r.height())
    }
    fn next_frame(&mut self, out: &mut RgbFrame) -> Result<bool, VisionError> {
        let buffer = self
            .camera
            .frame()
            .map_err(|e| VisionError::Webcam(format!("capture failed: {e}")))?;
        let r = buffer.resolution();
        out.resize(r.width(), r.height());
        buffer
            .decode_image_to_buffer::<RgbFormat>(&mut out.data)
            .map_err(|e| VisionError::Webcam(format!("cannot decode frame: {e}")))?;
        out.time_secs = self.started.elapsed().as_secs_f64();
        out.index = self.index;
        self.index += 1;
        Ok(true)
    }
}
