//! The host side of the tick: a tokio interval drives [`Ticker`] at the output rate with the
//! clocks read here, and [`HostOutput`] broadcasts its frames to the client sessions and sends
//! its VMC bundles on a UDP socket. Never awaits anything but its interval and the shutdown
//! signal; never blocks on a client.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::{broadcast, watch};
use tokio::time::MissedTickBehavior;

use crate::clock::{unix_nanos, TickTime};
use crate::engine::{OutFrame, TickContext, TickOutput, Ticker};
use crate::stats::Stats;

/// Where the server's tick puts what it produces: frames on the clients' broadcast, VMC
/// bundles on the output socket.
pub struct HostOutput {
    /// Fan-out to clients.
    pub frames: broadcast::Sender<OutFrame>,
    /// The VMC output socket (non-blocking), when there are receivers.
    pub vmc_socket: Option<UdpSocket>,
    /// Counters.
    pub stats: Arc<Stats>,
}

impl TickOutput for HostOutput {
    fn frame(&mut self, frame: OutFrame) {
        // Err only means "no client connected right now".
        let _ = self.frames.send(frame);
    }

    fn datagram(&mut self, to: SocketAddr, bundle: &[u8]) {
        // Non-blocking: a full socket buffer drops the datagram (counted) instead of stalling
        // the tick.
        let sent = (self.vmc_socket.as_ref()).is_some_and(|s| s.send_to(bundle, to).is_ok());
        if !sent {
            self.stats.vmc_send_errors.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Runs the tick at `rate_hz` until shutdown (`MissedTickBehavior::Skip`: a late tick is not
/// followed by a burst).
///
/// `wake` is notified when a camera's new pose is handed over: the tick runs at once instead
/// of up to a period later (that wait was the largest server stage of glass-to-wire at 60 Hz),
/// and its period restarts from there, so ticks follow the camera's frames. Two woken ticks
/// are never closer than [`MIN_TICK_GAP`]; a woken tick right after a periodic one does not
/// wait for it (a camera at the tick rate, or half of it, hands its pose over about when the
/// restarted period ends, and waiting the gap there was the handoff's p99). The output rate
/// stays under `rate_hz` plus the camera's frame rate.
pub async fn run_tick(
    ctx: TickContext,
    mut out: HostOutput,
    rate_hz: f64,
    wake: Arc<tokio::sync::Notify>,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut interval = tokio::time::interval(Duration::from_secs_f64(1.0 / rate_hz));
    interval.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut ticker = Ticker::new(ctx);
    let mut last_woken = tokio::time::Instant::now();
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = wake.notified() => {
                // Bounded rate: a burst of poses cannot spin the tick.
                tokio::time::sleep_until(last_woken + MIN_TICK_GAP).await;
                interval.reset();
                last_woken = tokio::time::Instant::now();
            }
            _ = shutdown.changed() => break,
        }
        let time = TickTime::now();
        ticker.perform(time);
        // Stamped when encoded (after the performers ran), as `send_nanos` is defined.
        ticker.publish(time, unix_nanos(), &mut out);
        out.stats.record_tick(time.instant.elapsed());
    }
}

/// The shortest time between two ticks when a camera's pose brings one forward (the highest
/// tick rate the server accepts).
pub const MIN_TICK_GAP: Duration = Duration::from_micros(1_000_000 / 240);
