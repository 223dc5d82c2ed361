//! A replayed clip as a source: a tokio task handing the clip's frames to the engine (its
//! door) on the clip's own frame grid.

use std::time::{Duration, Instant};

use rigcast_protocol::SourceState;
use rigcast_sources::Replay;
use tokio::sync::watch;
use tokio::time::MissedTickBehavior;

use rigcast_engine::clock::TickTime;
use rigcast_engine::inbox::SourceDoor;

/// Runs one replay source until shutdown or (non-looping) end of clip.
///
/// Samples only on the clip's frame grid (frame k at k × frame_time / speed), so streamed
/// poses are exactly the file's frames; a late wake-up skips to the current frame.
pub async fn run_replay_source(
    player: Replay,
    speed: f64,
    door: SourceDoor,
    mut shutdown: watch::Receiver<bool>,
) {
    // Sized once; sampled into, then copied through the door.
    let mut pose = door.subject().skeleton().rest_pose();
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
        let now = TickTime::now();
        let elapsed_secs = k as f64 * period;
        if player.sample(elapsed_secs, &mut pose).is_none() {
            door.health(SourceState::Finished);
            break;
        }
        // Captured when sampled (0: the time it is handed over).
        door.hand_over(now, 0, 0, &pose);
    }
}
