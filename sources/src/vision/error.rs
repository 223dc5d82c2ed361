//! The vision module's error enum.

use std::path::PathBuf;

use thiserror::Error;

/// Everything that can go wrong preparing, reading or running the vision pipeline.
#[derive(Debug, Error)]
pub enum VisionError {
    /// `scripts/setup-vision.sh` (`rigcast setup vision`) has not been run, or a file it
    /// installs is missing.
    #[error(
        "vision assets missing: {path} not found ({what}); run `rigcast setup vision` \
         (scripts/setup-vision.sh) first",
        path = path.display()
    )]
    NotSetUp {
        /// the missing file
        path: PathBuf,
        /// what it is
        what: &'static str,
    },
    /// The ONNX Runtime shared library could not be loaded or initialised.
    #[error("cannot load ONNX Runtime from {path}: {message}", path = path.display())]
    Runtime {
        /// the library
        path: PathBuf,
        /// why
        message: String,
    },
    /// Loading or running a model failed.
    #[error("model {path}: {message}", path = path.display())]
    Model {
        /// the model file
        path: PathBuf,
        /// why
        message: String,
    },
    /// A model output did not have the expected shape.
    #[error("model output {name}: expected {expected} values, got {actual}")]
    OutputShape {
        /// output tensor name
        name: &'static str,
        /// expected element count
        expected: usize,
        /// actual element count
        actual: usize,
    },
    /// A child process (ffmpeg/ffprobe) could not be started or failed.
    #[error("{program} on {input}: {message}")]
    Decoder {
        /// program name
        program: &'static str,
        /// the input being decoded
        input: String,
        /// why
        message: String,
    },
    /// The input file does not exist.
    #[error("{path}: no such file or directory", path = path.display())]
    NoInput {
        /// the path
        path: PathBuf,
    },
    /// A recorded landmark stream could not be read or holds no landmark records.
    #[error("landmark recording {path}: {message}")]
    Recording {
        /// the file (or source name)
        path: String,
        /// why
        message: String,
    },
    /// No camera, or the camera could not be opened / read.
    #[error("webcam: {0}")]
    Webcam(String),
    /// The camera stopped delivering (unplugged); the source keeps looking for it.
    #[error("webcam: {0}")]
    CameraLost(String),
    /// The built-in BlazePose skeleton failed to build (a programming error, reported anyway).
    #[error("BlazePose skeleton: {0}")]
    Skeleton(String),
    /// A frame had an impossible size.
    #[error("frame {width}x{height}: {message}")]
    BadFrame {
        /// width in pixels
        width: u32,
        /// height in pixels
        height: u32,
        /// why
        message: String,
    },
    /// A `#N` person beyond the people the pipeline tracks.
    #[error("person #{person}: only {num_people} people are tracked (#0..#{last})", last = num_people.saturating_sub(1))]
    NoSuchPerson {
        /// the person asked for
        person: usize,
        /// people tracked
        num_people: usize,
    },
    /// The pipeline thread could not be started.
    #[error("cannot start the pipeline thread: {0}")]
    Thread(String),
}
