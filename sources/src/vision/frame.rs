//! Frame input: the [`FrameSource`] trait that video files, image sequences and webcams share.

use super::error::VisionError;

/// One RGB frame, 8 bits per channel, rows top to bottom, no padding.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height × 3` bytes.
    pub data: Vec<u8>,
    /// Presentation time from the start of the source, seconds.
    pub time_secs: f64,
    /// Frame number from the start of the source.
    pub index: u64,
    /// Source pixels per frame pixel: above 1 when the decoder scaled the picture down to
    /// the model's resolution. Landmarks leave the pipeline in source pixels, so what a
    /// caller sees does not depend on the decode size.
    pub source_from_frame: f32,
    /// When a camera captured, handed over and decoded this frame (zero for files).
    pub clock: FrameClock,
}

/// A camera frame's times, Unix nanoseconds (all zero when the source is not a camera).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameClock {
    /// The driver's capture timestamp, mapped to the wall clock ("glass").
    pub captured_unix_nanos: u64,
    /// When the driver handed the frame over.
    pub dequeued_unix_nanos: u64,
    /// When it was decoded to RGB.
    pub decoded_unix_nanos: u64,
}

impl Default for RgbFrame {
    fn default() -> Self {
        RgbFrame::new(0, 0)
    }
}

impl RgbFrame {
    /// A black frame of the given size.
    pub fn new(width: u32, height: u32) -> RgbFrame {
        RgbFrame {
            width,
            height,
            data: vec![0; width as usize * height as usize * 3],
            time_secs: 0.0,
            index: 0,
            source_from_frame: 1.0,
            clock: FrameClock::default(),
        }
    }

    /// Resizes the buffer for `width × height` (allocates only when the size grows).
    pub fn resize(&mut self, width: u32, height: u32) {
        self.width = width;
        self.height = height;
        self.data.resize(width as usize * height as usize * 3, 0);
    }

    /// The pixel at (x, y), or black outside the frame.
    #[inline]
    pub fn pixel(&self, x: i32, y: i32) -> [u8; 3] {
        if x < 0 || y < 0 || x >= self.width as i32 || y >= self.height as i32 {
            return [0, 0, 0];
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// A source of RGB frames with timestamps: a video file, an image sequence or a webcam.
pub trait FrameSource: Send {
    /// Human-readable description (file name, camera name).
    fn describe(&self) -> &str;
    /// Nominal frames per second, when known.
    fn fps(&self) -> Option<f64>;
    /// Frame size in pixels.
    fn size(&self) -> (u32, u32);
    /// The camera mode in use, for a camera.
    fn camera_mode(&self) -> Option<super::camera_modes::CameraMode> {
        None
    }
    /// Reads the next frame into `out` (reusing its buffer). `Ok(false)` at the end of the input.
    /// [`VisionError::CameraLost`] is not the end: the source looks for its device again at
    /// the next call.
    fn next_frame(&mut self, out: &mut RgbFrame) -> Result<bool, VisionError>;
}

/// Frames held in memory (tests, benchmarks): yields them once, in order.
#[derive(Debug, Clone)]
pub struct MemorySource {
    frames: Vec<RgbFrame>,
    next: usize,
    fps: f64,
}

impl MemorySource {
    /// Frames at `fps`; every frame must have the size of the first.
    pub fn new(frames: Vec<RgbFrame>, fps: f64) -> MemorySource {
        MemorySource {
            frames,
            next: 0,
            fps,
        }
    }

    /// Starts again from the first frame.
    pub fn rewind(&mut self) {
        self.next = 0;
    }
}

impl FrameSource for MemorySource {
    fn describe(&self) -> &str {
        "memory"
    }
    fn fps(&self) -> Option<f64> {
        Some(self.fps)
    }
    fn size(&self) -> (u32, u32) {
        self.frames
            .first()
            .map(|f| (f.width, f.height))
            .unwrap_or((0, 0))
    }
    fn next_frame(&mut self, out: &mut RgbFrame) -> Result<bool, VisionError> {
        let Some(f) = self.frames.get(self.next) else {
            return Ok(false);
        };
        out.resize(f.width, f.height);
        out.data.copy_from_slice(&f.data);
        out.time_secs = f.time_secs;
        out.index = f.index;
        out.source_from_frame = f.source_from_frame;
        self.next += 1;
        Ok(true)
    }
}
