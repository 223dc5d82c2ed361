//! The time a tick runs at, and the clocks a host reads it from. The engine's own code reads
//! no clock: [`TickTime::now`] and [`unix_nanos`] are for the host (its tick task, its source
//! threads), which passes each tick its time, so a test can drive the engine on a simulated
//! clock. `unix_nanos` is the wall clock as the protocol stamps it (`capture_nanos`,
//! `send_nanos`).

use std::time::{SystemTime, UNIX_EPOCH};

/// Wall clock as Unix epoch nanoseconds.
pub fn unix_nanos() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// The time one tick runs at, read once by whatever drives the engine: the engine itself
/// reads no clock, so a test can drive it on a simulated one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TickTime {
    /// Monotonic time: phases, blends and retries are measured on it.
    pub instant: std::time::Instant,
    /// Wall-clock time as the protocol stamps it (a lost target's frames carry it).
    pub unix_nanos: u64,
}

impl TickTime {
    /// Now, from the system's clocks.
    pub fn now() -> TickTime {
        TickTime {
            instant: std::time::Instant::now(),
            unix_nanos: unix_nanos(),
        }
    }

    /// This time moved on by `by` on both clocks (a simulated clock's next tick).
    pub fn after(self, by: std::time::Duration) -> TickTime {
        TickTime {
            instant: self.instant + by,
            unix_nanos: self.unix_nanos.saturating_add(by.as_nanos() as u64),
        }
    }
}
