//! The host side of the engine: a loop that passes [`Engine`] what its [`Inbox`] holds (the
//! sources' poses and health, built mappings, commands) and the time (read here), and hands
//! out what it yields: [`HostOutput`] broadcasts frames to the client sessions and sends VMC
//! bundles on a UDP socket, events go on the clients' event broadcast, mappings to build go to
//! the mapper's thread. Never awaits anything but the engine's next wake-up, the inbox's wake
//! and the shutdown signal; never blocks on a client.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::Ordering;
use std::sync::Arc;

use rigcast_engine::clock::TickTime;
use rigcast_engine::events::Event;
use rigcast_engine::inbox::Inbox;
use rigcast_engine::tick::{EngineCommand, OutFrame, TickOutput};
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
/// frames to the client sessions, events to every client, mappings to build to the mapper,
/// each tick's duration to the counters), then sleeps until the wake-up it asked for, the
/// inbox's wake (a camera's new pose, a source's health, a mapping built, a command) or
/// shutdown; then passes it everything the inbox holds ([`Inbox::drain`]: a camera's pose
/// brings the tick forward, see `rigcast_engine::schedule::TickSchedule`) and the time now.
/// The only clocks read are here; every decision about when to tick is the engine's.
///
/// `mapper` is the mapper thread's queue: unbounded, since the inbox bounds what is on its
/// way (`rigcast_engine::inbox::COMMANDS_IN_FLIGHT`).
pub async fn run_engine(
    mut engine: Engine,
    mut out: HostOutput,
    events: broadcast::Sender<Event>,
    mapper: std::sync::mpsc::Sender<EngineCommand>,
    inbox: Inbox,
    wake: Arc<tokio::sync::Notify>,
    mut shutdown: watch::Receiver<bool>,
) {
    loop {
        let next = hand_out(&mut engine, &mut out, &events, &mapper);
        // Due already (the encoding of a tick that just performed): no sleep.
        if next > std::time::Instant::now() {
            tokio::select! {
                _ = tokio::time::sleep_until(next.into()) => {}
                _ = wake.notified() => {}
                _ = shutdown.changed() => break,
            }
        }
        inbox.drain(|input| engine.handle_input(input));
        engine.handle_input(Input::Timeout(TickTime::now()));
    }
}

/// Hands out everything the engine has yielded; returns when it next wants to run.
fn hand_out(
    engine: &mut Engine,
    out: &mut HostOutput,
    events: &broadcast::Sender<Event>,
    mapper: &std::sync::mpsc::Sender<EngineCommand>,
) -> std::time::Instant {
    loop {
        match engine.poll_output() {
            Output::Datagram { to, bundle } => out.datagram(to, bundle),
            Output::Frame(frame) => out.frame(frame),
            Output::Event(event) => {
                // Err only means no client is connected; the subjects keep their reports.
                let _ = events.send(event);
            }
            Output::Build(command) => {
                // Err only when the mapper has stopped (shutdown): nothing left to build.
                let _ = mapper.send(command);
            }
            Output::Ticked(started) => out
                .stats
                .record_tick(started.instant.elapsed(), started.instant),
            Output::Timeout(at) => return at,
        }
    }
}
