//! Serial IMU suits: a [`LiveSource`] reading orientation sensors from a serial port (or a
//! replayed byte stream), assigning sensors to bones, calibrating against a held pose and
//! reconnecting after the device is unplugged.
//!
//! ```text
//!   /dev/ttyUSB0 ─┐  bytes   ┌─ RawTap (recording)
//!   recording  ───┴─────────┤
//!                            └─ ImuParser ─ samples ─▶ ImuSolver ─▶ Pose (local rotations)
//!
//!   Connecting ──port opens, data──▶ Live ──unplug / silence──▶ Lost ──retry open──▶ Live
//! ```
//!
//! The port is reopened by path every [`SerialImuConfig::reconnect_secs`] while it is gone, so
//! a device that re-enumerates under a stable path (a udev `by-id` link, or a symlink) comes
//! back by itself.

pub mod parse;
pub mod ports;
pub mod solve;

use std::io::Read;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::Quat;
use rigcast_retarget::{Pose, Skeleton};
use serde::{Deserialize, Serialize};

pub use parse::{teapot_packet, witmotion_frame, ImuFormat, ImuParser, ImuSample};
pub use solve::ImuSolver;

use crate::error::SourceError;
use crate::live::{
    fit_pose, stamp_raw, HealthTracker, LiveSource, NextFrame, RawKind, RawPacket, RawTap,
    SourceState, SourceStatus,
};

/// One sensor → bone assignment.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SensorAssignment {
    /// Sensor id as sent by the device (CSV `id`; 0 for single-sensor binary formats).
    pub sensor: u32,
    /// Bone name in the source skeleton (default: Unity `HumanBodyBones` names).
    pub bone: String,
}

/// Configuration of a [`SerialImuSource`] (TOML-able).
///
/// ```toml
/// path = "/dev/serial/by-id/usb-imu-suit"
/// baud_rate = 115200
/// format = "csv"               # or "witmotion", "teapot"
/// sensors = [ { sensor = 0, bone = "Hips" }, { sensor = 1, bone = "LeftUpperArm" } ]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SerialImuConfig {
    /// Port path (a stable link is best: it is reopened by path after an unplug).
    pub path: PathBuf,
    /// Baud rate (ignored by pseudo-terminals and USB CDC devices).
    #[serde(default = "default_baud")]
    pub baud_rate: u32,
    /// Wire format.
    #[serde(default)]
    pub format: ImuFormat,
    /// Sensor → bone assignments.
    pub sensors: Vec<SensorAssignment>,
    /// Silence longer than this marks the source lost (default 0.5 s).
    #[serde(default = "default_lost_after")]
    pub lost_after_secs: f32,
    /// How often to retry opening a missing port (default 0.5 s).
    #[serde(default = "default_reconnect")]
    pub reconnect_secs: f32,
    /// Rotation from the sensors' world frame to the internal one, quaternion `[x, y, z, w]`
    /// (default identity: sensors already report +Y up).
    #[serde(default = "default_world")]
    pub world_from_sensor_world: [f32; 4],
}

fn default_baud() -> u32 {
    115_200
}
fn default_lost_after() -> f32 {
    0.5
}
fn default_reconnect() -> f32 {
    0.5
}
fn default_world() -> [f32; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

impl SerialImuConfig {
    /// CSV on `path` with the given assignments and defaults otherwise.
    pub fn csv(path: impl Into<PathBuf>, sensors: Vec<SensorAssignment>) -> Self {
        SerialImuConfig {
            path: path.into(),
            baud_rate: default_baud(),
            format: ImuFormat::Csv,
            sensors,
            lost_after_secs: default_lost_after(),
            reconnect_secs: default_reconnect(),
            world_from_sensor_world: default_world(),
        }
    }

    /// Parses a config from TOML text.
    pub fn from_toml(text: &str) -> Result<Self, SourceError> {
        toml::from_str(text).map_err(|e| SourceError::InvalidOption {
            reason: format!("serial IMU config: {e}"),
        })
    }
}

fn secs(name: &str, v: f32) -> Result<Duration, SourceError> {
    Duration::try_from_secs_f32(v)
        .ok()
        .filter(|d| !d.is_zero())
        .ok_or_else(|| SourceError::InvalidOption {
            reason: format!("{name} must be a positive number of seconds, got {v}"),
        })
}

/// Asks a running [`SerialImuSource`] (on another thread) to calibrate at its next read, and
/// reports how that went.
#[derive(Debug, Clone, Default)]
pub struct CalibrationHandle(Arc<CalibrationShared>);

#[derive(Debug, Default)]
struct CalibrationShared {
    requested: AtomicBool,
    /// The held pose of the pending request (`None`: the rest pose).
    pose: Mutex<Option<Pose>>,
    /// Attempts finished so far and the last one's result.
    outcome: Mutex<CalibrationOutcome>,
}

/// Attempts finished so far and the last one's result (`None` before the first).
type CalibrationOutcome = (u64, Option<Result<(), Arc<SourceError>>>);

impl CalibrationHandle {
    /// Requests a calibration against the rest pose; the result shows in the status detail.
    pub fn request(&self) {
        if let Ok(mut p) = self.0.pose.lock() {
            *p = None;
        }
        self.0.requested.store(true, Ordering::Release);
    }

    /// Requests a calibration against `pose` (e.g. an N-pose on the source skeleton).
    pub fn request_pose(&self, pose: Pose) {
        if let Ok(mut p) = self.0.pose.lock() {
            *p = Some(pose);
        }
        self.0.requested.store(true, Ordering::Release);
    }

    /// Number of calibration attempts the source has finished and the last one's result
    /// (`Err` carries the reason). Compare the count before and after a request to wait for
    /// its outcome.
    pub fn outcome(&self) -> (u64, Option<Result<(), Arc<SourceError>>>) {
        match self.0.outcome.lock() {
            Ok(g) => g.clone(),
            Err(p) => p.into_inner().clone(),
        }
    }

    /// Takes a pending request: `Some(held pose)` (inner `None` = rest pose).
    fn take(&self) -> Option<Option<Pose>> {
        if !self.0.requested.swap(false, Ordering::AcqRel) {
            return None;
        }
        Some(self.0.pose.lock().ok().and_then(|mut p| p.take()))
    }

    fn finish(&self, result: Result<(), Arc<SourceError>>) {
        if let Ok(mut g) = self.0.outcome.lock() {
            g.0 += 1;
            g.1 = Some(result);
        }
    }
}

/// Serial IMU live source.
pub struct SerialImuSource {
    name: String,
    config: SerialImuConfig,
    port: Option<Box<dyn serialport::SerialPort>>,
    replay: Option<(Vec<RawPacket>, usize)>,
    last_open_attempt: Option<Instant>,
    reconnect: Duration,
    parser: ImuParser,
    solver: ImuSolver,
    health: HealthTracker,
    tap: Option<Box<dyn RawTap>>,
    buf: [u8; 1024],
    calibration: CalibrationHandle,
}

impl SerialImuSource {
    /// A source on `skeleton` (see [`crate::live::humanoid::default_humanoid`]). The port is
    /// opened on the first [`LiveSource::next_frame`] and reopened after errors; a missing port
    /// is not an error here (the source stays `Connecting`).
    pub fn open(config: SerialImuConfig, skeleton: Arc<Skeleton>) -> Result<Self, SourceError> {
        let lost_after = secs("lost_after_secs", config.lost_after_secs)?;
        let reconnect = secs("reconnect_secs", config.reconnect_secs)?;
        let mut assignments = Vec::with_capacity(config.sensors.len());
        for a in &config.sensors {
            let bone = skeleton
                .bone(&a.bone)
                .ok_or_else(|| SourceError::InvalidOption {
                    reason: format!(
                        "sensor {}: no bone named {:?} in the skeleton",
                        a.sensor, a.bone
                    ),
                })?;
            assignments.push((a.sensor, bone));
        }
        let w = Quat::from_array(config.world_from_sensor_world);
        if !w.is_finite() || w.length() < 0.5 {
            return Err(SourceError::InvalidOption {
                reason: format!(
                    "world_from_sensor_world {:?} is not a rotation",
                    config.world_from_sensor_world
                ),
            });
        }
        let solver = ImuSolver::new(skeleton, assignments, w)?;
        Ok(SerialImuSource {
            name: format!("serial:{}", config.path.display()),
            parser: ImuParser::new(config.format),
            config,
            port: None,
            replay: None,
            last_open_attempt: None,
            reconnect,
            solver,
            health: HealthTracker::new(lost_after),
            tap: None,
            buf: [0; 1024],
            calibration: CalibrationHandle::default(),
        })
    }

    /// Replays recorded serial bytes (other packet kinds are skipped) through the same parser
    /// and solver, one chunk per read, as fast as `next_frame` is called.
    pub fn replay(
        packets: Vec<RawPacket>,
        config: SerialImuConfig,
        skeleton: Arc<Skeleton>,
    ) -> Result<Self, SourceError> {
        let mut source = SerialImuSource::open(config, skeleton)?;
        source.name = "serial:replay".into();
        source.replay = Some((
            packets
                .into_iter()
                .filter(|p| p.kind == RawKind::Serial)
                .collect(),
            0,
        ));
        Ok(source)
    }

    /// True when a replay delivered every chunk (always false for a port).
    pub fn replay_finished(&self) -> bool {
        matches!(&self.replay, Some((p, next)) if *next >= p.len())
    }

    /// Calibrates now against the rest pose (the performer holds the skeleton's rest pose,
    /// normally a T-pose), using each sensor's latest reading.
    pub fn calibrate(&mut self) -> Result<(), SourceError> {
        let rest = self.solver.skeleton().rest_pose();
        self.solver.calibrate(&rest)
    }

    /// Calibrates against another held pose (e.g. an N-pose) on the source skeleton.
    pub fn calibrate_to(&mut self, pose: &Pose) -> Result<(), SourceError> {
        self.solver.calibrate(pose)
    }

    /// True after a successful calibration.
    pub fn is_calibrated(&self) -> bool {
        self.solver.is_calibrated()
    }

    /// A handle to request calibration from another thread.
    pub fn calibration_handle(&self) -> CalibrationHandle {
        self.calibration.clone()
    }

    /// True while the port is open.
    pub fn is_connected(&self) -> bool {
        self.port.is_some()
    }

    /// Tries to open the port if it is closed and the retry interval has passed.
    fn ensure_open(&mut self, now: Instant) {
        if self.port.is_some() || self.replay.is_some() {
            return;
        }
        if matches!(self.last_open_attempt, Some(t) if now.duration_since(t) < self.reconnect) {
            return;
        }
        self.last_open_attempt = Some(now);
        let path = self.config.path.to_string_lossy();
        match serialport::new(path.as_ref(), self.config.baud_rate)
            .timeout(Duration::from_millis(10))
            .open()
        {
            Ok(port) => {
                self.port = Some(port);
                self.parser.reset();
                self.health.set_detail(&format!("{path}: open"));
            }
            Err(e) => {
                self.health
                    .on_device_lost(format!("{path}: cannot open ({e}); retrying"));
            }
        }
    }

    /// Reads one chunk; Ok(Some(n)) bytes in `self.buf` (or the replay chunk index via
    /// `Chunk`), Ok(None) on timeout.
    fn read_chunk(&mut self, deadline: Instant) -> Option<Chunk> {
        if let Some((packets, next)) = &mut self.replay {
            if *next < packets.len() {
                *next += 1;
                return Some(Chunk::Replay(*next - 1));
            }
            std::thread::sleep(deadline.saturating_duration_since(Instant::now()));
            return None;
        }
        let Some(port) = self.port.as_mut() else {
            // Closed: wait for the next reopen attempt or the deadline, whichever is first.
            let retry_at = self
                .last_open_attempt
                .map_or(Instant::now(), |t| t + self.reconnect);
            std::thread::sleep(
                retry_at
                    .min(deadline)
                    .saturating_duration_since(Instant::now()),
            );
            return None;
        };
        let wait = deadline
            .saturating_duration_since(Instant::now())
            .max(Duration::from_millis(1));
        if port.set_timeout(wait).is_err() {
            return None;
        }
        match port.read(&mut self.buf) {
            Ok(0) => {
                self.drop_port("end of stream".into());
                None
            }
            Ok(n) => Some(Chunk::Buf(n)),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => None,
            Err(e) => {
                self.drop_port(e.to_string());
                None
            }
        }
    }

    fn drop_port(&mut self, why: String) {
        self.port = None;
        self.parser.reset();
        self.last_open_attempt = Some(Instant::now());
        self.health.on_device_lost(format!(
            "{}: {why}; reconnecting",
            self.config.path.display()
        ));
    }
}

enum Chunk {
    Buf(usize),
    Replay(usize),
}

impl LiveSource for SerialImuSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn skeleton(&self) -> Option<Arc<Skeleton>> {
        Some(self.solver.skeleton().clone())
    }

    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(held) = self.calibration.take() {
                let result = match &held {
                    None => self.calibrate(),
                    Some(pose) => self.calibrate_to(pose),
                };
                let msg = match &result {
                    Ok(()) => "calibrated".to_string(),
                    Err(e) => e.to_string(),
                };
                self.health.set_detail(&msg);
                self.calibration.finish(result.map_err(Arc::new));
            }
            self.ensure_open(Instant::now());
            let Some(chunk) = self.read_chunk(deadline) else {
                self.health.poll(Instant::now());
                if Instant::now() >= deadline {
                    return Ok(None);
                }
                continue;
            };
            let bytes: &[u8] = match (&chunk, &self.replay) {
                (Chunk::Buf(n), _) => &self.buf[..*n],
                (Chunk::Replay(i), Some((packets, _))) => &packets[*i].bytes,
                (Chunk::Replay(_), None) => &[],
            };
            let (received, capture_nanos) = stamp_raw(&mut self.tap, RawKind::Serial, bytes);
            let solver = &mut self.solver;
            let mut samples = 0u32;
            let mut unassigned = 0u64;
            let dropped = self.parser.feed(bytes, |s| {
                if solver.set_reading(s.sensor, s.rotation) {
                    samples += 1;
                } else {
                    unassigned += 1;
                }
            });
            self.health.on_dropped(dropped + unassigned);
            if samples > 0 {
                self.health.on_input(received);
                fit_pose(out, self.solver.skeleton());
                self.solver.solve(out);
                return Ok(Some(self.health.produced(received, capture_nanos, false)));
            }
            if Instant::now() >= deadline {
                self.health.poll(Instant::now());
                return Ok(None);
            }
        }
    }

    fn status(&self) -> SourceStatus {
        let mut s = self.health.status();
        if s.state == SourceState::Live && !self.solver.is_calibrated() && s.detail.is_empty() {
            s.detail = "not calibrated".into();
        }
        s
    }

    fn set_raw_tap(&mut self, tap: Option<Box<dyn RawTap>>) {
        self.tap = tap;
    }
}
