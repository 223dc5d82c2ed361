//! The host side of the engine: a loop that passes [`Engine`] the time (read here) and
//! hands out what it yields: [`HostOutput`] broadcasts frames to the client sessions and sends
//! VMC bundles on a UDP socket, events go on the clients' event broadcast. Never awaits
//! anything but the engine's next wake-up, a camera's pose and the shutdown signal; never
//! blocks on a client.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::Ordering;
use std::sync::Arc;

use rigcast_engine::clock::TickTime;
use rigcast_engine::events::Event;
use rigcast_engine::tick::{OutFrame, TickOutput};
use rigcast_engine::{Engine, Input, Output};
use tokio::sync::{broadcast, watch};

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

/// Runs the engine until shutdown: hands out what it yields (datagrams on the UDP socket,
/// frames to the client sessions, events to every client, each tick's duration to the
/// counters), then sleeps until the wake-up it asked for, a camera's new pose (`wake`,
/// [`Input::Wake`]: the engine brings the tick forward, see
/// `rigcast_engine::schedule::TickSchedule`) or shutdown, and passes it the time then. The
/// only clocks read are here; every decision about when to tick is the engine's.
pub async fn run_engine(
    mut engine: Engine,
    mut out: HostOutput,
    events: broadcast::Sender<Event>,
    wake: Arc<tokio::sync::Notify>,
    mut shutdown: watch::Receiver<bool>,
) {
    loop {
        let next = hand_out(&mut engine, &mut out, &events);
        if next <= std::time::Instant::now() {
            // Due already (the encoding of a tick that just performed): no sleep.
            engine.handle_input(Input::Timeout(TickTime::now()));
            continue;
        }
        tokio::select! {
            _ = tokio::time::sleep_until(next.into()) => {
                engine.handle_input(Input::Timeout(TickTime::now()));
            }
            _ = wake.notified() => engine.handle_input(Input::Wake(TickTime::now())),
            _ = shutdown.changed() => break,
        }
    }
}

/// Hands out everything the engine has yielded; returns when it next wants to run.
fn hand_out(
    engine: &mut Engine,
    out: &mut HostOutput,
    events: &broadcast::Sender<Event>,
) -> std::time::Instant {
    loop {
        match engine.poll_output() {
            Output::Datagram { to, bundle } => out.datagram(to, bundle),
            Output::Frame(frame) => out.frame(frame),
            Output::Event(event) => {
                // Err only means no client is connected; the subjects keep their reports.
                let _ = events.send(event);
            }
            Output::Ticked(started) => out
                .stats
                .record_tick(started.instant.elapsed(), started.instant),
            Output::Timeout(at) => return at,
        }
    }
}
