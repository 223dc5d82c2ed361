//! VMC/OSC input: a [`LiveSource`] that listens for VMC (or mapped OSC) datagrams on UDP, or
//! replays recorded datagrams through the same decoder.
//!
//! ```text
//!   UDP :39539 ─┐                      ┌─ RawTap (recording)
//!               ├─ datagram ──────────┤
//!   recording ──┘                      └─ VmcDecoder ──▶ Pose on the learnt humanoid skeleton
//! ```
//!
//! The sender's skeleton is learnt from the `HumanBodyBones` it sends (see [`decoder`]), so
//! [`LiveSource::skeleton`] is `None` until the first complete frame. Silence longer than
//! [`VmcConfig::lost_after_secs`] marks the source `Lost`; the next good datagram makes it
//! `Live` again.

pub mod decoder;
pub mod mapping;

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_retarget::{Pose, Skeleton};
use serde::{Deserialize, Serialize};

pub use decoder::{FeedResult, VmcDecoder, VmcStats};
pub use mapping::{ArgField, CoordSpace, OscMapping, OscRule};

use crate::error::SourceError;
use crate::live::{
    fit_pose, stamp_raw, wait_until, HealthTracker, LiveSource, NextFrame, RawKind, RawPacket,
    RawTap, SourceState, SourceStatus,
};

/// Default VMC Marionette port.
pub const DEFAULT_VMC_PORT: u16 = 39539;

/// Largest UDP payload.
const MAX_DATAGRAM: usize = 65_536;

/// Configuration of a [`VmcSource`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VmcConfig {
    /// Address to bind (default 127.0.0.1: senders on this machine only).
    #[serde(default = "default_bind")]
    pub bind: IpAddr,
    /// Sender IP addresses whose datagrams are decoded; others are counted and dropped.
    /// Empty: every sender that can reach `bind`.
    #[serde(default)]
    pub allowed_senders: Vec<IpAddr>,
    /// UDP port (default 39539; 0 picks a free port, see [`VmcSource::local_addr`]).
    #[serde(default = "default_port")]
    pub port: u16,
    /// Silence longer than this marks the source lost (default 0.5 s).
    #[serde(default = "default_lost_after")]
    pub lost_after_secs: f32,
    /// Address mapping (default: VMC).
    #[serde(default = "OscMapping::vmc")]
    pub mapping: OscMapping,
}

fn default_bind() -> IpAddr {
    IpAddr::V4(Ipv4Addr::LOCALHOST)
}
fn default_port() -> u16 {
    DEFAULT_VMC_PORT
}
fn default_lost_after() -> f32 {
    0.5
}

impl Default for VmcConfig {
    fn default() -> Self {
        VmcConfig {
            bind: default_bind(),
            allowed_senders: Vec::new(),
            port: DEFAULT_VMC_PORT,
            lost_after_secs: default_lost_after(),
            mapping: OscMapping::vmc(),
        }
    }
}

impl VmcConfig {
    /// VMC on `port` with defaults otherwise (what `--source vmc:PORT` means).
    pub fn port(port: u16) -> Self {
        VmcConfig {
            port,
            ..VmcConfig::default()
        }
    }

    fn lost_after(&self) -> Result<Duration, SourceError> {
        Duration::try_from_secs_f32(self.lost_after_secs)
            .ok()
            .filter(|d| !d.is_zero())
            .ok_or_else(|| SourceError::InvalidOption {
                reason: format!(
                    "lost_after_secs must be a positive number of seconds, got {}",
                    self.lost_after_secs
                ),
            })
    }
}

enum Input {
    Udp {
        socket: UdpSocket,
        local: SocketAddr,
        allowed: Vec<IpAddr>,
        /// Datagrams from senders outside `allowed`.
        rejected: u64,
    },
    Replay {
        packets: Vec<RawPacket>,
        next: usize,
        realtime: bool,
        /// Wall-clock instant of the first packet and its recorded time.
        origin: Option<(Instant, u64)>,
    },
}

/// VMC/OSC live source.
pub struct VmcSource {
    name: String,
    input: Input,
    decoder: VmcDecoder,
    health: HealthTracker,
    tap: Option<Box<dyn RawTap>>,
    buf: Vec<u8>,
}

impl VmcSource {
    /// Binds the UDP socket and starts in the `Connecting` state.
    pub fn bind(config: VmcConfig) -> Result<VmcSource, SourceError> {
        let lost_after = config.lost_after()?;
        let socket = UdpSocket::bind(SocketAddr::new(config.bind, config.port))?;
        let local = socket.local_addr()?;
        Ok(VmcSource {
            name: format!("vmc:{}", local.port()),
            input: Input::Udp {
                socket,
                local,
                allowed: config.allowed_senders,
                rejected: 0,
            },
            decoder: VmcDecoder::new(config.mapping)?,
            health: HealthTracker::new(lost_after),
            tap: None,
            buf: vec![0; MAX_DATAGRAM],
        })
    }

    /// Replays recorded datagrams (packets of other kinds are skipped) through the same
    /// decoder. With `realtime`, packets are released at their recorded spacing; otherwise as
    /// fast as `next_frame` is called. After the last packet the source falls silent (and so
    /// turns `Lost` after the timeout).
    pub fn replay(
        packets: Vec<RawPacket>,
        config: VmcConfig,
        realtime: bool,
    ) -> Result<VmcSource, SourceError> {
        let lost_after = config.lost_after()?;
        let packets = packets
            .into_iter()
            .filter(|p| p.kind == RawKind::Osc)
            .collect();
        Ok(VmcSource {
            name: "vmc:replay".into(),
            input: Input::Replay {
                packets,
                next: 0,
                realtime,
                origin: None,
            },
            decoder: VmcDecoder::new(config.mapping)?,
            health: HealthTracker::new(lost_after),
            tap: None,
            buf: Vec::new(),
        })
    }

    /// The bound address (UDP input only).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match &self.input {
            Input::Udp { local, .. } => Some(*local),
            Input::Replay { .. } => None,
        }
    }

    /// Datagrams dropped because their sender is not in `allowed_senders`.
    pub fn rejected_senders(&self) -> u64 {
        match &self.input {
            Input::Udp { rejected, .. } => *rejected,
            Input::Replay { .. } => 0,
        }
    }

    /// True when a replay has delivered every packet (always false for UDP).
    pub fn replay_finished(&self) -> bool {
        match &self.input {
            Input::Udp { .. } => false,
            Input::Replay { packets, next, .. } => *next >= packets.len(),
        }
    }

    /// Decoder counters (malformed / reordered / dropped / ignored …).
    pub fn stats(&self) -> VmcStats {
        self.decoder.stats()
    }

    /// Latest blend shape values.
    pub fn blend_values(&self) -> &[(String, f32)] {
        self.decoder.blend_values()
    }

    /// Receives one datagram into `self.buf` (or the replay slot); returns its length, or
    /// None when `deadline` passed first.
    fn receive(&mut self, deadline: Instant) -> Option<Recv> {
        match &mut self.input {
            Input::Udp {
                socket,
                allowed,
                rejected,
                ..
            } => {
                let wait = deadline
                    .saturating_duration_since(Instant::now())
                    .max(Duration::from_millis(1));
                if socket.set_read_timeout(Some(wait)).is_err() {
                    return None;
                }
                match socket.recv_from(&mut self.buf) {
                    Ok((_, from)) if !allowed.is_empty() && !allowed.contains(&from.ip()) => {
                        *rejected += 1;
                        self.health.on_dropped(1);
                        self.health.set_detail(&format!(
                            "ignored {rejected} datagram(s) from senders not in allowed_senders (last {})",
                            from.ip()
                        ));
                        Some(Recv::Rejected)
                    }
                    Ok((n, _)) => Some(Recv::Buf(n)),
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) =>
                    {
                        None
                    }
                    // Other errors (e.g. ICMP-induced) are transient for an unconnected UDP
                    // socket: report and keep listening.
                    Err(e) => {
                        self.health.set_detail(&format!("receive error: {e}"));
                        None
                    }
                }
            }
            Input::Replay {
                packets,
                next,
                realtime,
                origin,
            } => {
                let packet = packets.get(*next)?;
                if *realtime {
                    let (start, first) =
                        *origin.get_or_insert((Instant::now(), packet.capture_nanos));
                    let due =
                        start + Duration::from_nanos(packet.capture_nanos.saturating_sub(first));
                    if !wait_until(due, deadline) {
                        return None;
                    }
                }
                *next += 1;
                Some(Recv::Replay(*next - 1))
            }
        }
    }
}

enum Recv {
    Buf(usize),
    Replay(usize),
    /// A datagram from a sender that is not allowed (already counted).
    Rejected,
}

impl LiveSource for VmcSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn skeleton(&self) -> Option<Arc<Skeleton>> {
        self.decoder.skeleton().cloned()
    }

    fn next_frame(&mut self, timeout: Duration, out: &mut Pose) -> NextFrame {
        let deadline = Instant::now() + timeout;
        loop {
            let Some(recv) = self.receive(deadline) else {
                let was_live = self.health.state() == SourceState::Live;
                self.health.poll(Instant::now());
                if was_live && self.health.state() == SourceState::Lost {
                    // The sender may come back restarted, with its clock at zero.
                    self.decoder.reset_sequence();
                    self.health.set_detail("no datagrams: lost");
                }
                return Ok(None);
            };
            if matches!(recv, Recv::Rejected) {
                if Instant::now() >= deadline {
                    return Ok(None);
                }
                continue;
            }
            let bytes: &[u8] = match (&recv, &self.input) {
                (Recv::Buf(n), _) => &self.buf[..*n],
                (Recv::Replay(i), Input::Replay { packets, .. }) => &packets[*i].bytes,
                (Recv::Replay(_) | Recv::Rejected, _) => &[],
            };
            let (received, capture_nanos) = stamp_raw(&mut self.tap, RawKind::Osc, bytes);
            let result = self.decoder.feed(bytes);
            self.health.on_dropped(result.dropped);
            if result.good_input {
                self.health.on_input(received);
            }
            if result.frame_ready {
                if let Some(skeleton) = self.decoder.skeleton() {
                    fit_pose(out, skeleton);
                    out.copy_from(self.decoder.pose());
                    return Ok(Some(self.health.produced(
                        received,
                        capture_nanos,
                        result.skeleton_changed,
                    )));
                }
            }
            if Instant::now() >= deadline {
                self.health.poll(Instant::now());
                return Ok(None);
            }
        }
    }

    fn status(&self) -> SourceStatus {
        self.health.status()
    }

    fn set_raw_tap(&mut self, tap: Option<Box<dyn RawTap>>) {
        self.tap = tap;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn listens_on_loopback_by_default_and_drops_senders_not_allowed() {
        let open = VmcSource::bind(VmcConfig::port(0)).unwrap();
        assert!(open.local_addr().unwrap().ip().is_loopback());
        let mut guarded = VmcSource::bind(VmcConfig {
            allowed_senders: vec!["127.0.0.2".parse().unwrap()],
            ..VmcConfig::port(0)
        })
        .unwrap();
        let to = guarded.local_addr().unwrap();
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        for _ in 0..3 {
            sender
                .send_to(b"/VMC/Ext/OK\0\0\0\0\0,i\0\0\0\0\0\x01", to)
                .unwrap();
        }
        let mut pose = Pose {
            rotations: Vec::new(),
            translations: Vec::new(),
        };
        // Bounded: three datagrams, then a timeout with nothing decoded.
        for _ in 0..3 {
            assert!(guarded
                .next_frame(Duration::from_millis(100), &mut pose)
                .unwrap()
                .is_none());
        }
        assert_eq!(guarded.rejected_senders(), 3);
        let status = guarded.status();
        assert_eq!(status.dropped, 3);
        assert!(
            status.detail.contains("allowed_senders"),
            "{}",
            status.detail
        );
        assert_eq!(
            guarded.stats().datagrams,
            0,
            "rejected datagrams are not decoded"
        );
    }
}
