//! A replayed clip as a source: a tokio task writing the clip's frames into its subject's
//! slot on the clip's own frame grid.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_protocol::SourceState;
use rigcast_sources::Replay;
use tokio::sync::watch;
use tokio::time::MissedTickBehavior;

use rigcast_engine::clock::unix_nanos;
use rigcast_engine::slot::FrameWriter;
use rigcast_engine::subject::Subject;

/// Runs one replay source until shutdown or (non-looping) end of clip.
///
/// Samples only on the clip's frame grid (frame k at k × frame_time / speed), so streamed
/// poses are exactly the file's frames; a late wake-up skips to the current frame.
pub async fn run_replay_source(
    player: Replay,
    speed: f64,
    tx: FrameWriter,
    subject: Arc<Subject>,
    mut shutdown: watch::Receiver<bool>,
) {
    // A floor on the period keeps a very fast speed setting from spinning the runtime; a
    // ceiling keeps a huge frame time (or a tiny speed) from overflowing the timer.
    let period = (player.frame_time_secs() / speed).clamp(1e-3, 3600.0);
    let period = if period.is_nan() { 1e-3 } else { period };
    let mut interval = tokio::time::interval(Duration::from_secs_f64(period));
    interval.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let start = Instant::now();
    let mut last_k = None;
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = shutdown.changed() => break,
        }
        // Snap to the frame grid: frame k is due at k × period after start.
        let k = (start.elapsed().as_secs_f64() / period).floor() as u64;
        if last_k == Some(k) {
            continue;
        }
        last_k = Some(k);
        let now = unix_nanos();
        let mut finished = false;
        let elapsed_secs = k as f64 * period;
        tx.send_modify(|f| match player.sample(elapsed_secs, &mut f.pose) {
            Some(_) => {
                f.seq += 1;
                f.capture_nanos = now;
            }
            None => finished = true,
        });
        if finished {
            subject.health.set_state(SourceState::Finished);
            break;
        }
        subject.stats.input.tick(Instant::now());
        subject
            .stats
            .last_capture_nanos
            .store(now, Ordering::Relaxed);
    }
}
