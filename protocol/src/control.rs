//! JSON control messages exchanged over the WebSocket as text frames.
//!
//! Every message is an object with a `"type"` tag in `snake_case`. Server → client messages are
//! [`ServerMessage`]; client → server requests are [`ClientMessage`]. Use
//! [`parse_client_message`] on incoming text: it tells apart "not JSON", "unknown type" and
//! "known type with bad fields", so the server can answer with a precise [`ErrorCode`] instead of
//! dropping the connection.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Whether a subject is a raw source or a target retargeted from a source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SubjectKind {
    /// Poses as produced by an input (file replay, VMC, …) on its own skeleton.
    Source,
    /// Poses retargeted onto a character skeleton from another subject.
    Target,
}

/// One streamed subject (a skeleton with a pose stream), as listed in `hello`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubjectInfo {
    /// Subject id, used in `subscribe` and in binary frame headers.
    pub id: u32,
    /// Human-readable name.
    pub name: String,
    /// Source or target.
    pub kind: SubjectKind,
    /// For targets: the subject they are retargeted from. `null` for sources.
    pub source: Option<u32>,
    /// Bones per frame (binary frames of this subject carry exactly this many rotations).
    pub num_bones: u32,
    /// Skeleton fingerprint, 16 lowercase hex digits; changes whenever the skeleton does.
    pub fingerprint: String,
    /// A target whose character file the server serves at `/v1/subjects/{id}/model.glb`:
    /// `"glb"` or `"vrm"`. Absent otherwise (BVH and `.gltf` targets, built-ins, sources).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
}

/// One bone of a `skeleton` message, in the skeleton's depth-first order (`parent < index`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoneInfo {
    /// Unique bone name.
    pub name: String,
    /// Index of the parent bone in the same list; `null` for a root.
    pub parent: Option<u32>,
    /// Rest local translation `[x, y, z]`, metres, internal space.
    pub rest_translation: [f32; 3],
    /// Rest local rotation `[x, y, z, w]`, internal space.
    pub rest_rotation: [f32; 4],
    /// Whether version 2 frames carry this bone's translation (the bones that move: roots,
    /// the chain down to the hips, bones whose source has position channels). Absent (older
    /// servers) reads as false.
    #[serde(default)]
    pub translated: bool,
}

/// One target bone of a `mapping` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MappingEntry {
    /// Target bone name.
    pub target: String,
    /// Source bone it follows, or `null` when unmapped.
    pub source: Option<String>,
    /// Match score normalised to 0..1 (0 for overrides).
    pub score: f32,
    /// Display colour (RGB 0..1) from a gradient along the skeleton, shared by both sides.
    pub color_gradient: [f32; 3],
    /// Display colour (RGB 0..1), random but stable per pair, easier to tell apart.
    pub color_random: [f32; 3],
    /// How sure the automatic mapper is of this bone, 0..1 (its margin over the best
    /// alternative; 1 for overrides, 0 when unmapped). Absent (older servers) reads as 1.
    #[serde(default = "full_confidence")]
    pub confidence: f32,
    /// Why a person should check this bone (low confidence, a runner-up close behind, a core
    /// bone left without a source), or absent when it is not flagged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flagged: Option<String>,
}

fn full_confidence() -> f32 {
    1.0
}

/// What kind of input a source subject is (`kind` in `source_status`, `[[sources]]` and
/// `--source KIND:ARG`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    /// A file or clip played back.
    Replay,
    /// VMC/OSC over UDP.
    Vmc,
    /// A serial IMU suit.
    Serial,
    /// Pose estimation on a video file.
    Video,
    /// Pose estimation on a webcam.
    Webcam,
    /// Another rigcast node's subject, relayed through the cluster (NATS). Never configured
    /// as a source: the cluster makes these.
    #[cfg_attr(feature = "clap", value(skip))]
    Remote,
}

impl std::fmt::Display for SourceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        wire_name(self, f)
    }
}

/// Writes a unit variant's serde name (`SourceKind::Vmc` → `vmc`): one spelling, serde's.
fn wire_name<T: Serialize>(value: &T, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
    match serde_json::to_value(value) {
        Ok(serde_json::Value::String(name)) => f.write_str(&name),
        _ => Err(std::fmt::Error),
    }
}

/// A source's connection state: the one name for it in every crate (`state` in
/// `source_status` and `/v1/status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceState {
    /// No usable input yet (port not open, no sender yet).
    Connecting,
    /// Input arriving within the source's timeout.
    Live,
    /// Input stopped (silence beyond the timeout, or the device went away).
    Lost,
    /// A replay reached its end (not looping).
    Finished,
    /// The source's task or thread stopped on an internal error; it produces nothing until
    /// the server restarts (`detail` says why).
    Failed,
}

impl std::fmt::Display for SourceState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        wire_name(self, f)
    }
}

/// A camera source's mode and where its frames' time goes (`camera` of [`SourceHealth`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraStatus {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Frames per second asked of the driver.
    pub fps: u32,
    /// Pixel format (`YUYV`, `MJPG`).
    pub format: String,
    /// The landmark model run on its frames (`lite`, `full`, `heavy`, `full-int8`).
    #[serde(default)]
    pub model: String,
    /// Per stage over the last frames (at most 256), in order: `capture` (the driver's
    /// timestamp to the frame handed over), `decode` (to RGB), `detect` (finding people),
    /// `landmarks` (the landmark model on tracked people), `solve` (smoothing, lengths,
    /// rotations), `glass_to_pose` (timestamp to pose published, all of the above).
    pub stages: Vec<StageLatency>,
}

/// Percentiles of one stage's time, milliseconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageLatency {
    /// The stage.
    pub stage: String,
    /// Median.
    pub p50_ms: f32,
    /// 99th percentile.
    pub p99_ms: f32,
    /// Frames measured.
    pub samples: u32,
}

/// Health of one source subject in a `source_status` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceHealth {
    /// Source subject id.
    pub subject: u32,
    /// Source kind: `replay`, `vmc`, `serial`, `video` or `webcam`.
    pub kind: SourceKind,
    /// `connecting`, `live`, `lost` or `finished` (a replay that reached its end).
    pub state: SourceState,
    /// Frames per second arriving from the source.
    pub input_fps: f32,
    /// Input arrival (or capture) to pose available, milliseconds (0 for replays).
    pub latency_ms: f32,
    /// Frames produced since start.
    pub frames: u64,
    /// Inputs dropped as malformed, reordered or unusable.
    pub dropped: u64,
    /// Human-readable detail: the last device error, or the calibration state of a serial
    /// suit (`not calibrated`, `calibrating (T-pose) in 3.0 s`, `calibrated (T-pose)`,
    /// `calibration failed: REASON`). Empty when there is nothing to say.
    #[serde(default)]
    pub detail: String,
    /// A camera's mode and stage latencies (absent for other sources).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraStatus>,
}

/// What drives a target character at the moment (`motion` in `source_status.targets`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TargetMotion {
    /// Its source(s): live motion.
    Live,
    /// The source came back; blending from the fallback to live motion.
    Resuming,
    /// Source lost: easing to (or standing at) the character's rest pose.
    Rest,
    /// Source lost: holding the last pose.
    Hold,
    /// Source lost: walking on the performer's idle motion graph.
    IdleGraph,
}

impl std::fmt::Display for TargetMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        wire_name(self, f)
    }
}

/// One target subject in a `source_status` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetHealth {
    /// Target subject id.
    pub subject: u32,
    /// What drives it.
    pub motion: TargetMotion,
    /// Why its processing is stopped, while it is (a fault in its mapping or foot lock; it is
    /// retried and clears when the input is sane again). Absent when healthy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fault: Option<String>,
}

/// One foot in a `footplants` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FootState {
    /// The target's foot (ankle) bone.
    pub bone: String,
    /// Held where it landed by the foot lock.
    pub planted: bool,
    /// The foot bone's world position in the subject's frame (internal space, metres):
    /// forward kinematics of frame `seq`. A planted foot's message is sent again whenever the
    /// foot has moved 2 % of its leg's length since (the foot lock turns a planted foot with the
    /// performer about the joint it stands on: a pivot on the ball carries the ankle round it),
    /// so this stays where the foot stands.
    pub position: [f32; 3],
}

/// Machine-readable reason in an `error` message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// The text is not valid JSON.
    BadJson,
    /// Valid JSON but not an object with a string `type`.
    MissingType,
    /// The `type` is not a known client message.
    UnknownType,
    /// Known `type`, but fields are missing or have the wrong type.
    InvalidFields,
    /// The client sent a binary WebSocket message; clients only send JSON text.
    BinaryNotAccepted,
    /// The message is larger than the server accepts.
    MessageTooLarge,
    /// A subject id that does not exist.
    UnknownSubject,
    /// The request is valid but not supported for this subject.
    Unsupported,
    /// `calibrate` named a subject that is not a calibratable live source (only serial IMU
    /// suits are).
    NotCalibratable,
    /// The message changes the server (`set_mapping`, `calibrate`) and this connection was
    /// opened without the control token.
    Unauthorized,
    /// Something went wrong on the server.
    Internal,
    /// A subject's processing failed (the message says why); the other subjects go on and
    /// this one is retried. Sent to every client, with `subject`.
    SubjectFaulted,
}

impl ErrorCode {
    /// The `snake_case` wire name.
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorCode::BadJson => "bad_json",
            ErrorCode::MissingType => "missing_type",
            ErrorCode::UnknownType => "unknown_type",
            ErrorCode::InvalidFields => "invalid_fields",
            ErrorCode::BinaryNotAccepted => "binary_not_accepted",
            ErrorCode::MessageTooLarge => "message_too_large",
            ErrorCode::UnknownSubject => "unknown_subject",
            ErrorCode::Unsupported => "unsupported",
            ErrorCode::NotCalibratable => "not_calibratable",
            ErrorCode::Unauthorized => "unauthorized",
            ErrorCode::Internal => "internal",
            ErrorCode::SubjectFaulted => "subject_faulted",
        }
    }
}

/// Messages the server sends as WebSocket text.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMessage {
    /// First message on every connection.
    Hello {
        /// The session's protocol (and frame) version: [`crate::PROTOCOL_VERSION`] until the
        /// client asks for another with `set_protocol`.
        protocol_version: u16,
        /// Every version the server can speak; absent (older servers) reads as `[1]`.
        #[serde(default = "only_version_1")]
        protocol_versions: Vec<u16>,
        /// The server's crate version.
        server_version: String,
        /// Output tick rate: frames per second per subject.
        tick_hz: f64,
        /// The subjects being streamed.
        subjects: Vec<SubjectInfo>,
    },
    /// A subject's skeleton; sent before that subject's first binary frame and whenever it
    /// changes (the fingerprint tells).
    Skeleton {
        /// Subject id.
        subject: u32,
        /// Subject name.
        name: String,
        /// Skeleton fingerprint (16 hex digits).
        fingerprint: String,
        /// Bones in depth-first order; frame rotation `i` belongs to bone `i`.
        bones: Vec<BoneInfo>,
    },
    /// The bone mapping of a target subject.
    Mapping {
        /// Target subject id.
        subject: u32,
        /// Source subject it is retargeted from.
        source_subject: u32,
        /// One entry per target bone.
        entries: Vec<MappingEntry>,
        /// What the skeleton analysis overruled or doubted on either side (for example names
        /// that mark the sides the other way round from the body); absent when empty.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        warnings: Vec<String>,
    },
    /// The client fell behind and frames were dropped for it; it stays connected.
    Lagged {
        /// Frames dropped since the last `lagged` message.
        missed: u64,
    },
    /// Answer to `ping`.
    Pong {
        /// The nonce from the ping.
        nonce: u64,
        /// Server wall clock, nanoseconds since the Unix epoch.
        server_nanos: u64,
    },
    /// A request could not be handled. The connection stays open.
    Error {
        /// Machine-readable reason.
        code: ErrorCode,
        /// Human-readable details.
        message: String,
        /// The subject it is about, when it is about one (`subject_faulted`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        subject: Option<u32>,
    },
    /// The subject list changed; same payload as `hello.subjects`.
    SubjectsChanged {
        /// The current subjects.
        subjects: Vec<SubjectInfo>,
    },
    /// Health of every source subject, about once per second.
    SourceStatus {
        /// One entry per source subject.
        sources: Vec<SourceHealth>,
        /// One entry per target subject (older servers omit it: read it as empty).
        #[serde(default)]
        targets: Vec<TargetHealth>,
    },
    /// A target's foot-lock state: sent whenever a foot is planted or lifts, when a planted foot
    /// has moved (it turns with the performer), and on connect, so clients can draw planted
    /// feet without polling `/v1/status`.
    Footplants {
        /// Target subject id.
        subject: u32,
        /// The `seq` of the subject's frame the positions were taken from.
        seq: u64,
        /// One entry per locked foot, in the foot lock's order; empty when the target's foot
        /// lock is off.
        feet: Vec<FootState>,
    },
    /// Answer to `set_protocol`: binary frames sent after this message use `version`.
    Protocol {
        /// The frame version now in use.
        version: u16,
    },
    /// A request was accepted (`set_mapping`, `calibrate`).
    Ack {
        /// The `type` of the request acknowledged.
        request: String,
        /// The subject it concerned.
        subject: u32,
    },
}

/// Messages a client sends as WebSocket text.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ClientMessage {
    /// Choose which subjects' frames to receive. `null` means all (the default).
    Subscribe {
        /// Subject ids, or `null` for all.
        subjects: Option<Vec<u32>>,
    },
    /// Round-trip probe; answered by `pong` with the same nonce.
    Ping {
        /// Any number; echoed back.
        nonce: u64,
    },
    /// Override parts of a target's bone mapping: target bone → source bone (`null` = unmap).
    SetMapping {
        /// Target subject id.
        subject: u32,
        /// Overrides by target bone name.
        overrides: BTreeMap<String, Option<String>>,
    },
    /// Calibrate a serial IMU source: after `delay_secs` the performer is taken to hold
    /// `pose`, and each sensor's reading at that moment becomes its mounting offset. The
    /// outcome shows in that source's `source_status` `detail`.
    Calibrate {
        /// Source subject id.
        subject: u32,
        /// The pose held (default `t`).
        #[serde(default)]
        pose: CalibrationPose,
        /// Seconds to wait before capturing (0..=60, default 0).
        #[serde(default)]
        delay_secs: f32,
    },
    /// Switch this connection's binary frames to another protocol version (one listed in
    /// `hello.protocol_versions`); answered by `protocol`, or `error` `unsupported`.
    SetProtocol {
        /// Requested version.
        version: u16,
    },
    /// Change how a performer (a target subject) is run; fields left out stay as they are.
    SetPerformer {
        /// Target subject id.
        subject: u32,
        /// Pin the character's feet while the source's are planted.
        #[serde(default)]
        foot_lock: Option<bool>,
    },
}

fn only_version_1() -> Vec<u16> {
    vec![1]
}

/// The pose a performer holds while calibrating.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CalibrationPose {
    /// T-pose: the source skeleton's rest pose (arms out sideways).
    #[default]
    T,
    /// N-pose: standing with the arms down along the body.
    N,
}

impl CalibrationPose {
    /// `"T-pose"` or `"N-pose"`, for messages.
    pub fn label(self) -> &'static str {
        match self {
            CalibrationPose::T => "T-pose",
            CalibrationPose::N => "N-pose",
        }
    }
}

/// Longest accepted `calibrate` delay, seconds.
pub const MAX_CALIBRATION_DELAY_SECS: f32 = 60.0;

/// The `type` tags [`ClientMessage`] understands.
pub const CLIENT_MESSAGE_TYPES: [&str; 6] = [
    "subscribe",
    "ping",
    "set_mapping",
    "calibrate",
    "set_protocol",
    "set_performer",
];

/// Why an incoming client text message was rejected.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{}: {message}", code.as_str())]
pub struct ParseError {
    /// Classification for the `error` reply.
    pub code: ErrorCode,
    /// Details (serde's message, with line/column where it has them).
    pub message: String,
}

/// Most characters of untrusted input an error message quotes.
pub const MAX_QUOTED_CHARS: usize = 64;

/// At most the first [`MAX_QUOTED_CHARS`] characters of untrusted `text` (with `…` when cut),
/// for error messages: an error never echoes more than a short prefix of what it refuses.
pub fn short_prefix(text: &str) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(MAX_QUOTED_CHARS) {
        Some((at, _)) => format!("{}…", &text[..at]).into(),
        None => text.into(),
    }
}

/// A message built from serde's or the parser's text, which may quote the input: cut to a few
/// times [`MAX_QUOTED_CHARS`].
fn bounded_message(message: String) -> String {
    let limit = 4 * MAX_QUOTED_CHARS;
    match message.char_indices().nth(limit) {
        Some((at, _)) => format!("{}…", &message[..at]),
        None => message,
    }
}

/// Parses a client text message, classifying failures (see [`ErrorCode`]).
pub fn parse_client_message(text: &str) -> Result<ClientMessage, ParseError> {
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| ParseError {
        code: ErrorCode::BadJson,
        message: bounded_message(format!("not valid JSON: {e}")),
    })?;
    let Some(kind) = value.get("type").and_then(|t| t.as_str()) else {
        return Err(ParseError {
            code: ErrorCode::MissingType,
            message: "expected a JSON object with a string field \"type\"".into(),
        });
    };
    if !CLIENT_MESSAGE_TYPES.contains(&kind) {
        return Err(ParseError {
            code: ErrorCode::UnknownType,
            message: format!(
                "unknown message type {:?}; expected one of {}",
                short_prefix(kind),
                CLIENT_MESSAGE_TYPES.join(", ")
            ),
        });
    }
    let kind = kind.to_string();
    serde_json::from_value(value).map_err(|e| ParseError {
        code: ErrorCode::InvalidFields,
        message: bounded_message(format!("bad fields in {kind:?} message: {e}")),
    })
}

impl ServerMessage {
    /// Serialises to JSON text. Serialising these plain structs cannot fail; should it ever,
    /// an `error` message is returned rather than panicking.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_else(|e| {
            format!(r#"{{"type":"error","code":"internal","message":"serialisation failed: {e}"}}"#)
        })
    }

    /// Shorthand for an `error` message.
    pub fn error(code: ErrorCode, message: impl Into<String>) -> ServerMessage {
        ServerMessage::Error {
            code,
            message: message.into(),
            subject: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kind_and_state_names_are_their_json_names() {
        for kind in [
            SourceKind::Replay,
            SourceKind::Vmc,
            SourceKind::Serial,
            SourceKind::Video,
            SourceKind::Webcam,
        ] {
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.to_string());
        }
        for state in [
            SourceState::Connecting,
            SourceState::Live,
            SourceState::Lost,
            SourceState::Finished,
            SourceState::Failed,
        ] {
            assert_eq!(serde_json::to_value(state).unwrap(), state.to_string());
        }
    }

    fn subjects() -> Vec<SubjectInfo> {
        vec![
            SubjectInfo {
                id: 0,
                name: "walk".into(),
                kind: SubjectKind::Source,
                source: None,
                num_bones: 31,
                fingerprint: "0123456789abcdef".into(),
                model: None,
            },
            SubjectInfo {
                id: 1,
                name: "robot".into(),
                kind: SubjectKind::Target,
                source: Some(0),
                num_bones: 12,
                fingerprint: "fedcba9876543210".into(),
                model: Some("vrm".into()),
            },
        ]
    }

    fn all_server_messages() -> Vec<ServerMessage> {
        vec![
            ServerMessage::Hello {
                protocol_version: 1,
                protocol_versions: vec![1, 2],
                server_version: "0.1.0".into(),
                tick_hz: 60.0,
                subjects: subjects(),
            },
            ServerMessage::Skeleton {
                subject: 0,
                name: "walk".into(),
                fingerprint: "0123456789abcdef".into(),
                bones: vec![
                    BoneInfo {
                        name: "Hips".into(),
                        parent: None,
                        rest_translation: [0.0, 1.0, 0.0],
                        rest_rotation: [0.0, 0.0, 0.0, 1.0],
                        translated: true,
                    },
                    BoneInfo {
                        name: "Spine".into(),
                        parent: Some(0),
                        rest_translation: [0.0, 0.1, 0.0],
                        rest_rotation: [0.0, 0.0, 0.5f32.sqrt(), 0.5f32.sqrt()],
                        translated: false,
                    },
                ],
            },
            ServerMessage::Mapping {
                subject: 1,
                source_subject: 0,
                warnings: vec!["names mark the sides the other way round".into()],
                entries: vec![
                    MappingEntry {
                        target: "body".into(),
                        source: Some("Hips".into()),
                        score: 0.9,
                        color_gradient: [1.0, 0.0, 0.0],
                        color_random: [0.2, 0.4, 0.6],
                        confidence: 0.95,
                        flagged: None,
                    },
                    MappingEntry {
                        target: "antenna".into(),
                        source: None,
                        score: 0.0,
                        color_gradient: [0.5, 0.5, 0.5],
                        color_random: [0.5, 0.5, 0.5],
                        confidence: 0.0,
                        flagged: Some("no source bone drives its role (head)".into()),
                    },
                ],
            },
            ServerMessage::Lagged { missed: 42 },
            ServerMessage::Pong {
                nonce: u64::MAX,
                server_nanos: 1_700_000_000_000_000_000,
            },
            ServerMessage::error(ErrorCode::UnknownType, "nope"),
            ServerMessage::SubjectsChanged {
                subjects: subjects(),
            },
            ServerMessage::Ack {
                request: "set_mapping".into(),
                subject: 1,
            },
            ServerMessage::Protocol { version: 2 },
            ServerMessage::Footplants {
                subject: 1,
                seq: 77,
                feet: vec![
                    FootState {
                        bone: "foot_l".into(),
                        planted: true,
                        position: [0.1, 0.08, 0.25],
                    },
                    FootState {
                        bone: "foot_r".into(),
                        planted: false,
                        position: [-0.1, 0.2, 0.5],
                    },
                ],
            },
            ServerMessage::SourceStatus {
                sources: vec![SourceHealth {
                    subject: 0,
                    kind: SourceKind::Vmc,
                    state: SourceState::Lost,
                    input_fps: 59.5,
                    latency_ms: 1.5,
                    frames: 1200,
                    dropped: 3,
                    detail: "calibrated (T-pose)".into(),
                    camera: None,
                }],
                targets: vec![
                    TargetHealth {
                        subject: 1,
                        motion: TargetMotion::IdleGraph,
                        fault: None,
                    },
                    TargetHealth {
                        subject: 2,
                        motion: TargetMotion::Live,
                        fault: Some("foot lock: a value is not finite".into()),
                    },
                ],
            },
            ServerMessage::Error {
                code: ErrorCode::SubjectFaulted,
                message: "stopped: boom".into(),
                subject: Some(3),
            },
        ]
    }

    #[test]
    fn server_messages_round_trip() {
        for m in all_server_messages() {
            let json = m.to_json();
            let back: ServerMessage = serde_json::from_str(&json).unwrap();
            assert_eq!(back, m, "{json}");
        }
    }

    #[test]
    fn footplants_message_is_the_documented_json() {
        let m = ServerMessage::Footplants {
            subject: 1,
            seq: 77,
            feet: vec![FootState {
                bone: "foot_l".into(),
                planted: true,
                position: [0.5, 0.0, -0.25],
            }],
        };
        assert_eq!(
            m.to_json(),
            r#"{"type":"footplants","subject":1,"seq":77,"feet":[{"bone":"foot_l","planted":true,"position":[0.5,0.0,-0.25]}]}"#
        );
    }

    #[test]
    fn server_messages_have_documented_shape() {
        let hello = serde_json::to_value(&all_server_messages()[0]).unwrap();
        assert_eq!(hello["type"], "hello");
        assert_eq!(hello["protocol_version"], 1);
        assert_eq!(hello["subjects"][0]["kind"], "source");
        assert!(hello["subjects"][0]["source"].is_null());
        assert_eq!(hello["subjects"][1]["kind"], "target");
        assert_eq!(hello["subjects"][1]["source"], 0);
        let skel = serde_json::to_value(&all_server_messages()[1]).unwrap();
        assert!(skel["bones"][0]["parent"].is_null());
        assert_eq!(
            skel["bones"][1]["rest_translation"][1].as_f64(),
            Some(0.1f32 as f64)
        );
        let err = serde_json::to_value(&all_server_messages()[5]).unwrap();
        assert_eq!(err["type"], "error");
        assert_eq!(err["code"], "unknown_type");
        let changed = serde_json::to_value(&all_server_messages()[6]).unwrap();
        assert_eq!(changed["type"], "subjects_changed");
    }

    #[test]
    fn client_messages_round_trip() {
        let mut overrides = BTreeMap::new();
        overrides.insert("arm".to_string(), Some("LeftArm".to_string()));
        overrides.insert("tail".to_string(), None);
        for m in [
            ClientMessage::Subscribe { subjects: None },
            ClientMessage::Subscribe {
                subjects: Some(vec![0, 3]),
            },
            ClientMessage::Ping { nonce: 7 },
            ClientMessage::SetMapping {
                subject: 1,
                overrides,
            },
            ClientMessage::Calibrate {
                subject: 2,
                pose: CalibrationPose::N,
                delay_secs: 3.0,
            },
            ClientMessage::SetProtocol { version: 2 },
        ] {
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(parse_client_message(&json).unwrap(), m, "{json}");
        }
    }

    #[test]
    fn parses_documented_examples() {
        assert_eq!(
            parse_client_message(r#"{"type":"subscribe","subjects":null}"#).unwrap(),
            ClientMessage::Subscribe { subjects: None }
        );
        assert_eq!(
            parse_client_message(r#"{"type":"subscribe","subjects":[2]}"#).unwrap(),
            ClientMessage::Subscribe {
                subjects: Some(vec![2])
            }
        );
        assert_eq!(
            parse_client_message(r#"{"type":"ping","nonce":5,"extra":true}"#).unwrap(),
            ClientMessage::Ping { nonce: 5 }
        );
    }

    #[test]
    fn protocol_negotiation_messages_have_documented_shape() {
        assert_eq!(
            parse_client_message(r#"{"type":"set_protocol","version":2}"#).unwrap(),
            ClientMessage::SetProtocol { version: 2 }
        );
        let reply = serde_json::to_value(ServerMessage::Protocol { version: 2 }).unwrap();
        assert_eq!(reply, serde_json::json!({"type": "protocol", "version": 2}));
        // An older server's hello (no protocol_versions) and skeleton (no translated) parse.
        let hello: ServerMessage = serde_json::from_str(
            r#"{"type":"hello","protocol_version":1,"server_version":"0","tick_hz":60.0,"subjects":[]}"#,
        )
        .unwrap();
        assert!(
            matches!(hello, ServerMessage::Hello { protocol_versions, .. } if protocol_versions == [1])
        );
        let bone: BoneInfo = serde_json::from_str(
            r#"{"name":"a","parent":null,"rest_translation":[0,0,0],"rest_rotation":[0,0,0,1]}"#,
        )
        .unwrap();
        assert!(!bone.translated);
    }

    #[test]
    fn parses_calibrate_examples() {
        assert_eq!(
            parse_client_message(r#"{"type":"calibrate","subject":0,"pose":"t","delay_secs":3.0}"#)
                .unwrap(),
            ClientMessage::Calibrate {
                subject: 0,
                pose: CalibrationPose::T,
                delay_secs: 3.0
            }
        );
        // pose and delay are optional.
        assert_eq!(
            parse_client_message(r#"{"type":"calibrate","subject":4}"#).unwrap(),
            ClientMessage::Calibrate {
                subject: 4,
                pose: CalibrationPose::T,
                delay_secs: 0.0
            }
        );
        let code = |s: &str| parse_client_message(s).unwrap_err().code;
        assert_eq!(
            code(r#"{"type":"calibrate","subject":0,"pose":"a"}"#),
            ErrorCode::InvalidFields
        );
        assert_eq!(code(r#"{"type":"calibrate"}"#), ErrorCode::InvalidFields);
        // A status without `detail` (older servers) still parses.
        let old = r#"{"type":"source_status","sources":[{"subject":0,"kind":"vmc","state":"live","input_fps":1.0,"latency_ms":0.0,"frames":1,"dropped":0}]}"#;
        let m: ServerMessage = serde_json::from_str(old).unwrap();
        assert!(
            matches!(m, ServerMessage::SourceStatus { sources, targets } if sources[0].detail.is_empty() && targets.is_empty())
        );
        assert_eq!(ErrorCode::NotCalibratable.as_str(), "not_calibratable");
        let e =
            serde_json::to_value(ServerMessage::error(ErrorCode::NotCalibratable, "x")).unwrap();
        assert_eq!(e["code"], "not_calibratable");
        let e = serde_json::to_value(ServerMessage::error(ErrorCode::Unauthorized, "x")).unwrap();
        assert_eq!(e["code"], ErrorCode::Unauthorized.as_str());
        assert_eq!(e["code"], "unauthorized");
    }

    #[test]
    fn classifies_bad_input() {
        let code = |s: &str| parse_client_message(s).unwrap_err().code;
        assert_eq!(code("{not json"), ErrorCode::BadJson);
        assert_eq!(code(""), ErrorCode::BadJson);
        assert_eq!(code("[1,2]"), ErrorCode::MissingType);
        assert_eq!(code(r#"{"type":3}"#), ErrorCode::MissingType);
        assert_eq!(code(r#"{"type":"dance"}"#), ErrorCode::UnknownType);
        assert_eq!(code(r#"{"type":"ping"}"#), ErrorCode::InvalidFields);
        assert_eq!(
            code(r#"{"type":"ping","nonce":"x"}"#),
            ErrorCode::InvalidFields
        );
        assert_eq!(
            code(r#"{"type":"ping","nonce":-1}"#),
            ErrorCode::InvalidFields
        );
        assert_eq!(
            code(r#"{"type":"subscribe","subjects":"all"}"#),
            ErrorCode::InvalidFields
        );
        let e = parse_client_message(r#"{"type":"ping"}"#).unwrap_err();
        assert!(e.message.contains("nonce"), "{}", e.message);
    }
}
