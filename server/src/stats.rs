//! Counters behind `GET /v1/status`. Written by the hot paths with atomics (and one
//! uncontended mutex for the tick-duration window), read by the status handler. A subject's
//! own counters are the engine's (`rigcast_engine::stats`, re-exported here).

use std::collections::BTreeMap;
use std::sync::atomic::AtomicU64;
use std::sync::Mutex;
use std::time::Duration;

use rigcast_engine::stats::RateMeter;

/// Ticks kept for the duration percentiles (about 17 s at 60 Hz).
const TICK_WINDOW: usize = 1024;

/// Per-client counters.
#[derive(Debug)]
pub struct ClientStats {
    /// Frames sent.
    pub frames_sent: AtomicU64,
    /// Frames dropped because the client lagged.
    pub missed_frames: AtomicU64,
    /// Snapshots sent after control messages were lost to lag.
    pub control_resyncs: AtomicU64,
    /// Peer address, for display.
    pub peer: String,
    /// What the client may do.
    pub access: crate::access::Access,
}

impl ClientStats {
    /// Zeroed counters for a client.
    pub fn new(peer: String, access: crate::access::Access) -> ClientStats {
        ClientStats {
            frames_sent: AtomicU64::new(0),
            missed_frames: AtomicU64::new(0),
            control_resyncs: AtomicU64::new(0),
            peer,
            access,
        }
    }
}

/// Server-wide counters.
#[derive(Debug)]
pub struct Stats {
    /// Ticks run.
    pub output: RateMeter,
    /// Frames dropped across all clients.
    pub dropped_frames: AtomicU64,
    /// VMC datagrams that could not be sent.
    pub vmc_send_errors: AtomicU64,
    /// Snapshots sent to clients that lost control messages to lag.
    pub control_resyncs: AtomicU64,
    /// Clients dropped for accepting nothing for the stall timeout.
    pub stalled_disconnects: AtomicU64,
    /// Frames not handed to NATS (cluster mode): publish failures and frames the publisher
    /// fell behind on.
    pub cluster_publish_errors: AtomicU64,
    /// Frames received from NATS that were malformed and dropped (cluster mode).
    pub cluster_bad_frames: AtomicU64,
    /// Control requests this node forwarded to the nodes owning their subjects.
    pub cluster_control_forwarded: AtomicU64,
    /// Control requests from other nodes this node carried out (or answered with an error
    /// about the request itself).
    pub cluster_control_served: AtomicU64,
    /// Control requests from other nodes refused: wrong token, stale, replayed, malformed.
    pub cluster_control_refused: AtomicU64,
    /// Other nodes' subjects found while running (after the start).
    pub cluster_subjects_discovered: AtomicU64,
    /// Connected clients by id.
    pub clients: Mutex<BTreeMap<u64, std::sync::Arc<ClientStats>>>,
    tick_micros: Mutex<TickWindow>,
}

#[derive(Debug)]
struct TickWindow {
    values: [u32; TICK_WINDOW],
    len: usize,
    next: usize,
}

impl Default for Stats {
    fn default() -> Self {
        Stats {
            output: RateMeter::default(),
            dropped_frames: AtomicU64::new(0),
            vmc_send_errors: AtomicU64::new(0),
            control_resyncs: AtomicU64::new(0),
            stalled_disconnects: AtomicU64::new(0),
            cluster_publish_errors: AtomicU64::new(0),
            cluster_bad_frames: AtomicU64::new(0),
            cluster_control_forwarded: AtomicU64::new(0),
            cluster_control_served: AtomicU64::new(0),
            cluster_control_refused: AtomicU64::new(0),
            cluster_subjects_discovered: AtomicU64::new(0),
            clients: Mutex::new(BTreeMap::new()),
            tick_micros: Mutex::new(TickWindow {
                values: [0; TICK_WINDOW],
                len: 0,
                next: 0,
            }),
        }
    }
}

pub use rigcast_protocol::status::TickPercentiles;

impl Stats {
    /// Records the duration `d` of the tick that started at `started` (no allocation).
    pub fn record_tick(&self, d: Duration, started: std::time::Instant) {
        self.output.tick(started);
        if let Ok(mut w) = self.tick_micros.lock() {
            let micros = d.as_micros().min(u32::MAX as u128) as u32;
            let i = w.next;
            w.values[i] = micros;
            w.next = (i + 1) % TICK_WINDOW;
            w.len = (w.len + 1).min(TICK_WINDOW);
        }
    }

    /// Percentiles over the recent window.
    pub fn tick_percentiles(&self) -> TickPercentiles {
        let mut values = match self.tick_micros.lock() {
            Ok(w) => w.values[..w.len].to_vec(),
            Err(_) => return TickPercentiles::default(),
        };
        if values.is_empty() {
            return TickPercentiles::default();
        }
        values.sort_unstable();
        let at = |p: f64| values[((values.len() - 1) as f64 * p).round() as usize];
        TickPercentiles {
            p50: at(0.5),
            p90: at(0.9),
            p99: at(0.99),
            max: at(1.0),
            samples: values.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_known_values() {
        let s = Stats::default();
        for us in 1..=100u64 {
            s.record_tick(Duration::from_micros(us), std::time::Instant::now());
        }
        let p = s.tick_percentiles();
        assert_eq!(
            (p.p50, p.p90, p.p99, p.max, p.samples),
            (51, 90, 99, 100, 100)
        );
        // The window forgets old ticks.
        for _ in 0..TICK_WINDOW {
            s.record_tick(Duration::from_micros(7), std::time::Instant::now());
        }
        assert_eq!(s.tick_percentiles().max, 7);
    }
}

/// How often the cluster's shared mapping cache served or took a table.
#[derive(Debug, Default)]
pub struct MappingShareCounts {
    /// Tables taken from the bucket instead of computed.
    pub fetched: AtomicU64,
    /// Tables computed here and put in the bucket.
    pub shared: AtomicU64,
}
