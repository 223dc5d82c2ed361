//! The crate's one error enum.
//!
//! Parsers work on bytes and report positions (line for text formats, byte offset for binary
//! ones); the file-level entry points ([`crate::load_clip`] and friends) wrap those errors in
//! [`SourceError::File`] so that the message also names the file.

use std::path::PathBuf;

use rigcast_retarget::RetargetError;
use thiserror::Error;

/// Everything that can go wrong reading or writing a source file.
#[derive(Debug, Error)]
pub enum SourceError {
    /// The OS refused to read or write a file.
    #[error("{path}: {source}", path = path.display())]
    Io {
        /// the file
        path: PathBuf,
        /// the OS error
        #[source]
        source: std::io::Error,
    },
    /// A stream (not a named file) failed.
    #[error("I/O error: {0}")]
    Stream(#[from] std::io::Error),
    /// An error inside a named file.
    #[error("{path}: {inner}", path = path.display())]
    File {
        /// the file
        path: PathBuf,
        /// what went wrong inside it
        inner: Box<SourceError>,
    },
    /// A text format contains bytes that are not UTF-8.
    #[error("byte offset {offset}: text is not valid UTF-8")]
    NotUtf8 {
        /// first invalid byte
        offset: usize,
    },
    /// The text does not follow the format's grammar.
    #[error("line {line}: expected {expected}, found {found:?}")]
    Syntax {
        /// 1-based line
        line: usize,
        /// what the grammar wanted here
        expected: String,
        /// what was there
        found: String,
    },
    /// A number could not be parsed (or is NaN/infinite).
    #[error("line {line}: expected a finite number, found {token:?}")]
    BadNumber {
        /// 1-based line
        line: usize,
        /// the offending token
        token: String,
    },
    /// A BVH channel name is not one of X/Y/Z position/rotation.
    #[error("line {line}: unknown channel {name:?} (expected Xposition, Yposition, Zposition, Xrotation, Yrotation or Zrotation)")]
    UnknownChannel {
        /// 1-based line
        line: usize,
        /// the channel name
        name: String,
    },
    /// `CHANNELS n` is followed by a different number of names.
    #[error("line {line}: CHANNELS declares {declared} channels but lists {found}")]
    ChannelCount {
        /// 1-based line
        line: usize,
        /// the declared count
        declared: usize,
        /// names actually listed
        found: usize,
    },
    /// The file ended before the structure was complete.
    #[error("line {line}: file ends early; expected {expected}")]
    UnexpectedEof {
        /// last line of the file
        line: usize,
        /// what was still needed
        expected: String,
    },
    /// A BVH file has a hierarchy but no `MOTION` section.
    #[error("line {line}: missing MOTION section after the hierarchy")]
    MissingMotion {
        /// last line of the file
        line: usize,
    },
    /// The number of frame lines differs from `Frames:`.
    #[error("Frames: declares {declared} frames but the file holds {found}")]
    FrameCountMismatch {
        /// declared frames
        declared: usize,
        /// frames present
        found: usize,
    },
    /// A frame line has the wrong number of values.
    #[error("line {line}: expected {expected} channel values, found {found}")]
    FrameValues {
        /// 1-based line
        line: usize,
        /// total channels of the hierarchy
        expected: usize,
        /// values on the line
        found: usize,
    },
    /// A glTF/GLB document could not be parsed or validated.
    #[error("glTF: {message}")]
    Gltf {
        /// the parser's message
        message: String,
    },
    /// A glTF file has neither a skin nor VRM humanoid bones, so there is no skeleton to read.
    #[error("glTF has no skeleton: expected a skin or VRM humanoid bones")]
    NoSkeleton,
    /// An accessor points outside its buffer, or has an unexpected type.
    #[error("glTF accessor {accessor}: {reason}")]
    BadAccessor {
        /// accessor index
        accessor: usize,
        /// what is wrong
        reason: String,
    },
    /// The requested animation does not exist.
    #[error("animation {requested:?} not found; available: {available:?}")]
    AnimationNotFound {
        /// index or name asked for
        requested: String,
        /// names of the animations in the file
        available: Vec<String>,
    },
    /// A recording does not start with the rigcast magic.
    #[error("not a rigcast recording: expected magic {expected:?}, found {found:?}")]
    BadMagic {
        /// the expected bytes
        expected: [u8; 8],
        /// what the file starts with
        found: Vec<u8>,
    },
    /// A recording of a newer major version.
    #[error("recording format version {found} is not supported (this build reads major version {supported})")]
    UnsupportedVersion {
        /// the file's major version
        found: u16,
        /// the major version this build reads
        supported: u16,
    },
    /// A record ends before its declared length.
    #[error("byte offset {offset}: truncated record: expected {expected} bytes, found {found}")]
    TruncatedRecord {
        /// offset of the record header
        offset: u64,
        /// bytes the record needs
        expected: u64,
        /// bytes available
        found: u64,
    },
    /// A length prefix larger than any valid record (a corrupt file).
    #[error("byte offset {offset}: record length {length} exceeds the limit of {max} bytes")]
    RecordTooLarge {
        /// offset of the record header
        offset: u64,
        /// the declared length
        length: u64,
        /// the limit
        max: u64,
    },
    /// A record's payload is inconsistent.
    #[error("byte offset {offset}: bad record: {reason}")]
    BadRecord {
        /// offset of the record header
        offset: u64,
        /// what is wrong
        reason: String,
    },
    /// The file contains no frames where frames are required.
    #[error("no animation frames: {reason}")]
    NoFrames {
        /// where they were expected
        reason: String,
    },
    /// The file extension does not name a format this operation supports.
    #[error("unsupported file extension {extension:?}; expected one of {expected}")]
    UnsupportedExtension {
        /// the extension found
        extension: String,
        /// the supported extensions
        expected: &'static str,
    },
    /// A replay or option value is out of range.
    #[error("invalid option: {reason}")]
    InvalidOption {
        /// what is wrong
        reason: String,
    },
    /// The input goes beyond one of the readers' bounds (nesting depth, counts, sizes, times;
    /// see `ARCHITECTURE.md`'s threat model). Refused before the work or memory it would take.
    #[error("{what} {found} is beyond the limit of {limit}")]
    Limit {
        /// what was measured, with its place (`"line 12: joint depth"`)
        what: String,
        /// the value found
        found: String,
        /// the bound
        limit: String,
    },
    /// The decoded skeleton or clip failed validation.
    #[error(transparent)]
    Skeleton(#[from] RetargetError),
}

impl SourceError {
    /// A [`SourceError::Limit`].
    pub fn limit(
        what: impl Into<String>,
        found: impl std::fmt::Display,
        limit: impl std::fmt::Display,
    ) -> SourceError {
        SourceError::Limit {
            what: what.into(),
            found: found.to_string(),
            limit: limit.to_string(),
        }
    }

    /// Wraps this error with the file it came from (IO errors already carry it).
    pub fn in_file(self, path: impl Into<PathBuf>) -> SourceError {
        match self {
            e @ (SourceError::Io { .. } | SourceError::File { .. }) => e,
            other => SourceError::File {
                path: path.into(),
                inner: Box::new(other),
            },
        }
    }

    /// The innermost error (unwrapping [`SourceError::File`]), handy for matching on kinds.
    pub fn root(&self) -> &SourceError {
        match self {
            SourceError::File { inner, .. } => inner.root(),
            other => other,
        }
    }
}
