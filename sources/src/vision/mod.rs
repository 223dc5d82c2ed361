//! Webcam and video pose estimation: BlazePose landmarks through ONNX Runtime, turned into
//! rotations of a BlazePose source skeleton.
//!
//! ```text
//!  FrameSource (ffmpeg video / image sequence at the model's resolution, webcam, memory)
//!      │ RgbFrame (RGB8 + timestamp; decoded ahead on a thread)
//!      ▼
//!  PoseTracker ── per identity slot #0..#N-1: ROI from its last aux landmarks 33/34
//!      │          ──▶ LandmarkModel (ort), once per tracked person per frame
//!      │          (someone lost / slots free: PersonDetector finds people, or the
//!      │           candidate-crop search without the detector model)
//!      ▼ Landmarks per person (33 image + world points, visibility, presence)
//!      │   ◀── LandmarkReplaySource: recorded landmarks re-enter here (no model, no camera)
//!  LandmarkStages: One Euro smoothing per coordinate, world landmarks into the camera's axes
//!      │          with their across-picture shape from the image (perspective), the world
//!      │          output smoothed as MediaPipe smooths its world landmarks, each point by its
//!      │          visibility (world_smoothing), constant limb lengths (world)
//!      ▼
//!  PoseSolver ── two-direction aim per bone, twist from hip line / palm / foot plane,
//!      │         confidence per bone: hold, then ease to rest
//!      ▼
//!  Pose on the BlazePose skeleton ──▶ VisionSource (LiveSource) / `rigcast pose`
//!                                  └─▶ SharedVision: one pipeline thread, one PersonSource
//!                                      (LiveSource) per tracked person `#0`, `#1`, …
//! ```
//!
//! The runtime library and models are installed by `scripts/setup-vision.sh` (`rigcast setup
//! vision`) under [`VisionAssets`]; nothing is downloaded at run time.

/// `Debug` showing only the named fields (`field` or `field.method()`): these types hold model
/// sessions, tensors, frame buffers and threads whose contents are of no use in a log line
/// (several are not `Debug` at all), so deriving is not an option.
macro_rules! debug_fields {
    ($ty:ident { $($field:ident $(. $method:ident ())?),* $(,)? }) => {
        impl std::fmt::Debug for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.debug_struct(stringify!($ty))
                    $(.field(stringify!($field), &self.$field $(.$method())?))*
                    .finish()
            }
        }
    };
}

pub mod assets;
pub mod body;
mod bound;
pub mod camera_modes;
mod change;
pub mod detector;
pub mod error;
pub mod ffmpeg;
pub mod frame;
pub mod landmarks;
pub mod lengths;
pub mod model;
pub mod one_euro;
pub mod perspective;
pub mod pipeline;
pub mod read_ahead;
mod readings;
pub mod replay;
pub mod roi;
pub mod shared;
mod sides;
pub mod solve;
pub mod source;
pub mod stages;
pub mod tracker;
#[cfg(feature = "webcam")]
pub mod webcam;
pub mod world_smoothing;

pub use assets::{ModelKind, VisionAssets};
pub use body::blazepose_skeleton;
pub use camera_modes::{CameraMode, PixelFormat, WebcamOptions};
pub use error::VisionError;
pub use ffmpeg::{DecodeSize, FfmpegSource};
pub use frame::{FrameClock, FrameSource, MemorySource, RgbFrame};
pub use landmarks::{Landmarks, LANDMARK_NAMES, NUM_LANDMARKS};
pub use model::{InputRange, LandmarkModel};
pub use pipeline::{PipelineConfig, PosePipeline};
pub use replay::LandmarkReplaySource;
pub use shared::{PersonSource, SharedVision};
pub use solve::{PoseSolver, SolverConfig};
pub use source::VisionSource;
pub use stages::LandmarkStages;
pub use tracker::{Finder, PoseTracker, TrackerConfig};
#[cfg(feature = "webcam")]
pub use webcam::{describe_cameras, list_cameras, CameraInfo, Webcam};

/// Opens camera `index` (see [`Webcam::open`]). Without the `webcam` cargo feature this is
/// always an error that says how to get it.
pub fn open_webcam(
    index: u32,
    options: WebcamOptions,
) -> Result<Box<dyn FrameSource>, VisionError> {
    #[cfg(feature = "webcam")]
    {
        Ok(Box::new(Webcam::open(index, options)?))
    }
    #[cfg(not(feature = "webcam"))]
    {
        let _ = (index, options);
        Err(VisionError::Webcam(NO_WEBCAM_SUPPORT.into()))
    }
}

/// What a build without the `webcam` feature says when asked for a camera.
pub const NO_WEBCAM_SUPPORT: &str = "this build has no webcam support (it was built with \
     `--no-default-features`); build it with the default features, which need libclang-dev \
     (installed by scripts/install-apps.sh)";
