//! `rigcast serve --record FILE.rcr`: one recording with every subject's skeleton and frames
//! and the raw packets of live sources (through their raw taps), written as it streams and
//! flushed about once a second.
//!
//! ```text
//!  live source threads ──RecordingTap──┐
//!  recorder thread (polls each subject's slot at the tick rate) ──┼──▶ Mutex<RecordingWriter<File>>
//!  live skeleton changes ─────────────────────────────────────────┘
//! ```

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use rigcast_retarget::Skeleton;
use rigcast_sources::live::RecordingTap;
use rigcast_sources::recording::RecordingWriter;

use rigcast_engine::subject::Subject;

/// The writer type shared by the recorder and the raw taps.
pub type SharedWriter = Arc<Mutex<RecordingWriter<BufWriter<File>>>>;

/// A writer lock poisoned by a panicking holder (a raw tap's thread).
const POISONED: &str = "the recording writer is unusable after a panic";

/// Flush interval.
const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// An open recording.
pub struct Recorder {
    writer: SharedWriter,
    health: Arc<RecorderHealth>,
}

/// How a recording is going; shared with the status handler (which must not hold the
/// recorder itself: finishing it needs the last reference).
#[derive(Debug)]
pub struct RecorderHealth {
    path: PathBuf,
    /// Failed writes (the recording goes on).
    pub errors: AtomicU64,
    /// The latest failure.
    last_error: Mutex<Option<String>>,
}

impl RecorderHealth {
    /// Where it records and how that is going.
    pub fn status(&self) -> RecordingStatus {
        RecordingStatus {
            path: self.path.display().to_string(),
            errors: self.errors.load(Ordering::Relaxed),
            last_error: self.last_error.lock().ok().and_then(|e| e.clone()),
        }
    }
}

pub use rigcast_protocol::status::RecordingStatus;

impl Recorder {
    /// Creates the file.
    pub fn create(path: &Path) -> anyhow::Result<Recorder> {
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        let writer = RecordingWriter::new(BufWriter::new(file))
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(Recorder {
            writer: Arc::new(Mutex::new(writer)),
            health: Arc::new(RecorderHealth {
                path: path.to_path_buf(),
                errors: AtomicU64::new(0),
                last_error: Mutex::new(None),
            }),
        })
    }

    /// Its health, for `/v1/status`.
    pub fn health(&self) -> Arc<RecorderHealth> {
        self.health.clone()
    }

    /// A raw tap for live source `subject`.
    pub fn tap(&self, subject: u32) -> RecordingTap<BufWriter<File>> {
        RecordingTap::new(self.writer.clone(), subject)
    }

    fn count<T>(&self, r: Result<T, String>) {
        if let Err(e) = r {
            self.health.errors.fetch_add(1, Ordering::Relaxed);
            if let Ok(mut last) = self.health.last_error.lock() {
                *last = Some(e);
            }
        }
    }

    /// Writes a skeleton record.
    pub fn skeleton(&self, subject: u32, name: &str, skeleton: &Arc<Skeleton>) {
        let r = match self.writer.lock() {
            Ok(mut w) => w
                .write_skeleton(subject, name, skeleton)
                .map_err(|e| format!("writing a skeleton record: {e}")),
            Err(_) => Err(POISONED.to_string()),
        };
        self.count(r);
    }

    /// Polls the subjects at `rate_hz` and writes every new frame until `stop`; flushes about
    /// once a second and at the end (call on a dedicated thread).
    pub fn run(&self, subjects: &[Arc<Subject>], rate_hz: f64, stop: &AtomicBool) {
        let mut last: Vec<(u64, u64)> = vec![(0, 0); subjects.len()];
        for s in subjects {
            let shape = s.shape();
            self.skeleton(s.id, &shape.info.name, &shape.skeleton);
            last[s.id as usize].1 = shape.skeleton.fingerprint();
        }
        let period = Duration::from_secs_f64(1.0 / rate_hz.max(1.0));
        let mut last_flush = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(period);
            for (s, (seq, fp)) in subjects.iter().zip(&mut last) {
                let frame = s.latest.borrow();
                if frame.capture_nanos == 0 || frame.seq == *seq {
                    continue;
                }
                let shape = s.shape();
                if shape.skeleton.fingerprint() != *fp {
                    // Live skeleton changes are written by the source thread; this catches
                    // the case where the frame got here first.
                    *fp = shape.skeleton.fingerprint();
                    self.skeleton(s.id, &shape.info.name, &shape.skeleton);
                }
                *seq = frame.seq;
                let r = match self.writer.lock() {
                    Ok(mut w) => w
                        .write_frame(s.id, frame.seq, frame.capture_nanos, &frame.pose)
                        .map_err(|e| format!("writing a frame: {e}")),
                    Err(_) => Err(POISONED.to_string()),
                };
                self.count(r);
            }
            if last_flush.elapsed() >= FLUSH_EVERY {
                last_flush = Instant::now();
                self.flush();
            }
        }
        self.flush();
    }

    /// Flushes buffered records to the file.
    pub fn flush(&self) {
        let r = match self.writer.lock() {
            Ok(mut w) => w.flush().map_err(|e| format!("flushing: {e}")),
            Err(_) => Err(POISONED.to_string()),
        };
        self.count(r);
    }

    /// Writes the end record (when no tap holds the writer any more) or flushes.
    pub fn finish(self) {
        match Arc::try_unwrap(self.writer) {
            Ok(m) => {
                if let Ok(w) = m.into_inner() {
                    if let Err(e) = w.finish() {
                        tracing::warn!("recording: cannot write the end record: {e}");
                    }
                }
            }
            Err(shared) => {
                if let Ok(mut w) = shared.lock() {
                    if let Err(e) = w.flush() {
                        tracing::warn!("recording: cannot flush: {e}");
                    }
                }
            }
        }
    }
}
