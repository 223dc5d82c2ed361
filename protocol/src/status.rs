//! The `GET /v1/status` body (documented in PROTOCOL.md): the server's counters, one record
//! per subject and per client. Serialised by the server, deserialisable by clients and tests.

use serde::{Deserialize, Serialize};

use crate::control::{CameraStatus, SourceHealth, SourceState, StageLatency, SubjectKind};

/// What a client may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClientAccess {
    /// Watch only.
    ReadOnly,
    /// Change the server (opened with the control token).
    Control,
}

/// `GET /v1/status` body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Server crate version.
    pub server_version: String,
    /// Configured output rate.
    pub tick_hz: f64,
    /// Measured output rate (ticks per second).
    pub output_rate_hz: f64,
    /// Per-subject input.
    pub subjects: Vec<SubjectStatus>,
    /// Connected clients.
    pub clients: ClientsStatus,
    /// Frames dropped for lagging clients, total since start.
    pub dropped_frames_total: u64,
    /// VMC datagrams that failed to send.
    pub vmc_send_errors: u64,
    /// Tick duration percentiles (µs) over the last ~1024 ticks.
    pub tick_micros: TickPercentiles,
    /// Connections against the cap.
    pub connections: ConnectionsStatus,
    /// Clients that lost control messages to lag and were sent a fresh snapshot, total.
    pub control_resyncs_total: u64,
    /// Clients dropped because their socket accepted nothing for the stall timeout, total.
    pub stalled_disconnects_total: u64,
    /// The `--record` recording (`null` when not recording).
    pub recording: Option<RecordingStatus>,
    /// Cluster mode's counters (absent when the node is not in a cluster).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster: Option<ClusterStatus>,
}

/// This node's part in a cluster (NATS), in the status.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClusterStatus {
    /// This node's site name.
    pub site: String,
    /// Frames not handed to NATS.
    pub publish_errors: u64,
    /// Malformed frames received from NATS and dropped.
    pub bad_frames: u64,
    /// Control requests forwarded to the nodes owning their subjects.
    pub control_forwarded: u64,
    /// Control requests from other nodes carried out or answered here.
    pub control_served: u64,
    /// Control requests from other nodes refused (wrong token, stale, replayed, malformed).
    pub control_refused: u64,
    /// Other nodes' subjects found after this node started.
    pub subjects_discovered: u64,
    /// Mapping tables taken from the cluster's shared cache instead of being computed here.
    pub mappings_from_cluster: u64,
    /// Mapping tables computed here and put in the shared cache.
    pub mappings_shared: u64,
}

/// Connections in the status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConnectionsStatus {
    /// Open now (WebSocket clients and requests in progress).
    pub open: usize,
    /// The cap.
    pub max: usize,
    /// Refused with 503 since start (evicted unfinished requests included).
    pub refused_total: u64,
    /// Unfinished requests evicted to make way for newer connections.
    pub evicted_total: u64,
    /// Soft open-file limit of the process (`null` when unknown).
    pub fd_limit: Option<u64>,
}

/// One subject in the status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubjectStatus {
    /// id
    pub id: u32,
    /// name
    pub name: String,
    /// bones
    pub num_bones: u32,
    /// Frames per second arriving from the source.
    pub input_fps: f64,
    /// Frames produced since start.
    pub input_frames: u64,
    /// Capture time of the latest frame, Unix ns (0 = none yet).
    pub last_capture_nanos: u64,
    /// `source` or `target`.
    pub kind: SubjectKind,
    /// Source subjects of a target.
    pub inputs: Vec<u32>,
    /// Health of a source (replays: `live` or `finished`).
    pub source: Option<SourceHealth>,
    /// UDP address a VMC source listens on.
    pub listen: Option<String>,
    /// Skeleton changes applied (live sources learn their sender's skeleton).
    pub skeleton_changes: u64,
    /// Frames held back because skeleton changes came faster than the rate limit.
    pub skeleton_frames_limited: u64,
    /// Poses refused where they enter the engine (not finite, a translation beyond 10 km, a
    /// quaternion that is not a rotation), total. Older servers omit it.
    #[serde(default)]
    pub rejected_poses: u64,
    /// Why the latest pose was refused (`null` when none has been).
    #[serde(default)]
    pub last_rejection: Option<String>,
    /// Why this subject's processing is stopped now (`null` when it is healthy): a fault in
    /// its mapping or foot lock, retried until the input is sane again.
    #[serde(default)]
    pub fault: Option<String>,
    /// Faults caught in this subject's processing since start.
    #[serde(default)]
    pub faults_total: u64,
    /// A target's feet under its foot lock and whether each is held now (`null` without a
    /// foot lock).
    pub footplants: Option<Vec<FootStatus>>,
    /// Where its frames' time went between the source and the WebSocket, over its last
    /// frames (at most 256; each frame once, at its first tick and its first write), in order:
    /// `handoff` (the source's pose handed to the engine → the tick that takes it starts),
    /// `retarget` (that tick's performers), `send` (encoded →
    /// written to a client's socket), `glass_to_wire` (the frame's capture time → written).
    /// Live sources and the targets following them only (replays and fallback poses are not
    /// timed); stages not measured yet are left out; absent before the first frame is sent.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub latency: Vec<StageLatency>,
}

/// One foot of a target's foot lock.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FootStatus {
    /// The foot bone.
    pub bone: String,
    /// Held where it was planted.
    pub planted: bool,
}

/// Clients in the status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClientsStatus {
    /// Connected clients.
    pub count: usize,
    /// Each client.
    pub list: Vec<ClientStatus>,
}

/// One client in the status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClientStatus {
    /// connection id
    pub id: u64,
    /// peer address
    pub peer: String,
    /// frames sent
    pub frames_sent: u64,
    /// frames dropped because it lagged
    pub missed_frames: u64,
    /// `read_only` or `control` (opened with the token)
    pub access: ClientAccess,
    /// times it lost control messages to lag and got a fresh snapshot
    pub control_resyncs: u64,
}

/// Tick duration percentiles in microseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TickPercentiles {
    /// median
    pub p50: u32,
    /// 90th percentile
    pub p90: u32,
    /// 99th percentile
    pub p99: u32,
    /// maximum
    pub max: u32,
    /// ticks in the window
    pub samples: usize,
}

/// The recording in `/v1/status`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RecordingStatus {
    /// The file.
    pub path: String,
    /// Failed writes since start (records lost; the recording goes on).
    pub errors: u64,
    /// The latest failure (`null` when none).
    pub last_error: Option<String>,
}

/// A live source's own report of its health (the sources crate's live sources write it; the
/// server folds it into [`SourceHealth`] for `/v1/status` and `source_status`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceStatus {
    /// Connection state.
    pub state: SourceState,
    /// Frames produced per second, measured over the last half second or so.
    pub input_fps: f32,
    /// Time from input arrival (or capture, when the device stamps it) to the frame being
    /// returned, milliseconds, smoothed.
    pub latency_ms: f32,
    /// Frames produced since the source was created.
    pub frames: u64,
    /// Packets, lines or messages that were malformed, reordered or unusable and were dropped.
    pub dropped: u64,
    /// Human-readable detail (last error, port name, calibration state).
    pub detail: String,
    /// A camera's mode and stage latencies (cameras only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraStatus>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{SourceKind, SourceState};

    #[test]
    fn status_round_trips_through_json() {
        let status = Status {
            server_version: "0.1.0".into(),
            tick_hz: 60.0,
            output_rate_hz: 59.5,
            subjects: vec![SubjectStatus {
                id: 0,
                name: "demo".into(),
                num_bones: 25,
                input_fps: 60.0,
                input_frames: 312,
                last_capture_nanos: 1,
                kind: SubjectKind::Source,
                inputs: vec![],
                source: Some(SourceHealth {
                    subject: 0,
                    kind: SourceKind::Replay,
                    state: SourceState::Live,
                    input_fps: 60.0,
                    latency_ms: 0.0,
                    frames: 312,
                    dropped: 0,
                    detail: String::new(),
                    camera: None,
                }),
                listen: None,
                skeleton_changes: 0,
                skeleton_frames_limited: 0,
                rejected_poses: 2,
                last_rejection: Some("bone 0: a translation is beyond 10 km".into()),
                fault: None,
                faults_total: 1,
                footplants: Some(vec![FootStatus {
                    bone: "foot_l".into(),
                    planted: true,
                }]),
                latency: vec![StageLatency {
                    stage: "glass_to_wire".into(),
                    p50_ms: 31.5,
                    p99_ms: 40.25,
                    samples: 256,
                }],
            }],
            clients: ClientsStatus {
                count: 1,
                list: vec![ClientStatus {
                    id: 1,
                    peer: "127.0.0.1:50412".into(),
                    frames_sent: 600,
                    missed_frames: 0,
                    access: ClientAccess::ReadOnly,
                    control_resyncs: 0,
                }],
            },
            dropped_frames_total: 0,
            vmc_send_errors: 0,
            tick_micros: TickPercentiles::default(),
            connections: ConnectionsStatus {
                open: 1,
                max: 960,
                refused_total: 0,
                evicted_total: 0,
                fd_limit: Some(1024),
            },
            control_resyncs_total: 0,
            stalled_disconnects_total: 0,
            recording: None,
            cluster: None,
        };
        let json = serde_json::to_value(&status).unwrap();
        assert_eq!(json["subjects"][0]["kind"], "source");
        assert_eq!(json["subjects"][0]["source"]["state"], "live");
        assert_eq!(json["clients"]["list"][0]["access"], "read_only");
        let back: Status = serde_json::from_value(json).unwrap();
        assert_eq!(back, status);
    }
}
