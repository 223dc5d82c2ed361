//! The `calibrate` request: a client asks a serial IMU source to take the performer's current
//! sensor readings as the held T- or N-pose.
//!
//! ```text
//!  client ─calibrate{subject,pose,delay}─▶ check (source? serial? delay sane?) ─▶ ack | error
//!                                             │ text = "calibrating (T-pose) in 3.0 s"
//!                                             ▼ tokio task: sleep(delay)
//!                CalibrationHandle::request / request_pose(n_pose) ─▶ source thread, next read
//!                                             │ poll outcome (≤ 2 s)
//!                                             ▼
//!         text = "calibrated (T-pose)" | "calibration failed: REASON" ─▶ source_status (at once)
//! ```
//!
//! The text is the source's `detail` in `source_status` and `/v1/status`, which is how the
//! `rigcast calibrate` command learns the outcome.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_engine::subject::{CalibrationOutcome, Calibrator};
use rigcast_protocol::control::{CalibrationPose, ErrorCode, MAX_CALIBRATION_DELAY_SECS};
use rigcast_retarget::Pose;
use rigcast_sources::serial::CalibrationHandle;
use tokio::sync::broadcast;

use rigcast_engine::subject::Subject;
use rigcast_protocol::SourceState;

/// How long the source thread may take to act on a request (it checks at every read, at
/// least every 50 ms).
const RESPONSE_TIMEOUT: Duration = Duration::from_secs(2);

/// Prefix of the pending text.
pub const PENDING_PREFIX: &str = "calibrating";
/// Prefix of the success text.
pub const SUCCESS_PREFIX: &str = "calibrated";
/// Prefix of the failure text.
pub const FAILURE_PREFIX: &str = "calibration failed";

/// A serial suit's calibration handle, as the engine carries it with the subject.
#[derive(Debug)]
pub struct SerialCalibration(pub CalibrationHandle);

impl Calibrator for SerialCalibration {
    fn request(&self) {
        self.0.request();
    }

    fn request_pose(&self, pose: Pose) {
        self.0.request_pose(pose);
    }

    fn outcome(&self) -> CalibrationOutcome {
        let (count, result) = self.0.outcome();
        (count, result.map(|r| r.map_err(|e| e.to_string())))
    }
}

/// Why a `calibrate` request was refused; [`CalibrateRefusal::code`] and the text make the
/// `error` reply.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrateRefusal {
    /// No subject has this id.
    #[error("unknown subject id {subject}")]
    UnknownSubject {
        /// the id asked for
        subject: u32,
    },
    /// The subject is not a serial IMU source.
    #[error("subject {subject} ({name}) is {what}; only serial IMU sources can be calibrated")]
    NotCalibratable {
        /// the id
        subject: u32,
        /// its name
        name: String,
        /// what it is instead (`a target (retargeted character)`, `a vmc source`)
        what: String,
    },
    /// The delay is out of range.
    #[error("delay_secs {delay_secs} must be between 0 and {MAX_CALIBRATION_DELAY_SECS}")]
    BadDelay {
        /// the delay asked for
        delay_secs: f32,
    },
}

impl CalibrateRefusal {
    /// The machine-readable reason in the `error` reply.
    pub fn code(&self) -> ErrorCode {
        match self {
            CalibrateRefusal::UnknownSubject { .. } => ErrorCode::UnknownSubject,
            CalibrateRefusal::NotCalibratable { .. } => ErrorCode::NotCalibratable,
            CalibrateRefusal::BadDelay { .. } => ErrorCode::InvalidFields,
        }
    }
}

/// Validates a `calibrate` request and starts it; `Err` is the `error` reply.
pub fn start(
    subjects: &Arc<Vec<Arc<Subject>>>,
    events: &broadcast::Sender<rigcast_engine::events::Event>,
    subject: u32,
    pose: CalibrationPose,
    delay_secs: f32,
) -> Result<(), CalibrateRefusal> {
    let Some(s) = subjects.get(subject as usize).filter(|s| s.id == subject) else {
        return Err(CalibrateRefusal::UnknownSubject { subject });
    };
    let name = s.info().name;
    let Some(cal) = s.calibration.as_ref() else {
        let what = match s.source_kind {
            None => "a target (retargeted character)".to_string(),
            Some(kind) => format!("a {kind} source"),
        };
        return Err(CalibrateRefusal::NotCalibratable {
            subject,
            name,
            what,
        });
    };
    if !(delay_secs.is_finite() && (0.0..=MAX_CALIBRATION_DELAY_SECS).contains(&delay_secs)) {
        return Err(CalibrateRefusal::BadDelay { delay_secs });
    }
    let generation = cal.generation.fetch_add(1, Ordering::AcqRel) + 1;
    cal.set_text(format!(
        "{PENDING_PREFIX} ({}) in {delay_secs:.1} s",
        pose.label()
    ));
    // Err only means no client is listening right now.
    let _ = events.send(rigcast_engine::events::Event::source_status(
        subjects,
        std::time::Instant::now(),
    ));
    let subjects = subjects.clone();
    let events = events.clone();
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_secs_f32(delay_secs)).await;
        let Some(s) = subjects.get(subject as usize) else {
            return;
        };
        let text = run(s, pose).await;
        if let Some(cal) = &s.calibration {
            // A newer request owns the text now.
            if cal.generation.load(Ordering::Acquire) == generation {
                cal.set_text(text);
                // Err only means no client is listening right now.
                let _ = events.send(rigcast_engine::events::Event::source_status(
                    &subjects,
                    std::time::Instant::now(),
                ));
            }
        }
    });
    Ok(())
}

/// Asks the source thread to calibrate and waits for its outcome; returns the status text.
async fn run(s: &Subject, pose: CalibrationPose) -> String {
    let Some(cal) = s.calibration.as_ref() else {
        return format!("{FAILURE_PREFIX}: not a calibratable source");
    };
    let state = s.health.state();
    if state != SourceState::Live {
        return format!("{FAILURE_PREFIX}: the source is {state} (no sensor data to capture)");
    }
    let (before, _) = cal.handle.outcome();
    match pose {
        CalibrationPose::T => cal.handle.request(),
        CalibrationPose::N => cal
            .handle
            .request_pose(rigcast_sources::live::humanoid::n_pose(&s.skeleton())),
    }
    let deadline = Instant::now() + RESPONSE_TIMEOUT;
    loop {
        tokio::time::sleep(Duration::from_millis(5)).await;
        let (count, result) = cal.handle.outcome();
        if count > before {
            return match result {
                Some(Ok(())) => format!("{SUCCESS_PREFIX} ({})", pose.label()),
                Some(Err(reason)) => format!("{FAILURE_PREFIX}: {reason}"),
                None => format!("{FAILURE_PREFIX}: no result"),
            };
        }
        if Instant::now() >= deadline {
            return format!(
                "{FAILURE_PREFIX}: the source did not respond within {} s",
                RESPONSE_TIMEOUT.as_secs()
            );
        }
    }
}
