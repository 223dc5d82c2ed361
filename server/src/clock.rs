//! The wall clock as the protocol stamps it (`capture_nanos`, `send_nanos`): its own module so
//! that every layer reading it depends on nothing above it.

use std::time::{SystemTime, UNIX_EPOCH};

/// Wall clock as Unix epoch nanoseconds.
pub fn unix_nanos() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}
