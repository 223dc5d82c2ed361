//! When the engine wants to run next: the tick at its period, brought forward by a camera's
//! pose, and the slower checks off the tick (planted feet, faults and motions). Plain
//! arithmetic on the times the host passes in; nothing here reads a clock or sleeps.
//!
//! ```text
//!  periodic:  t0 ── P ── t0+P ── P ── …   a late tick skips the deadlines it missed
//!  woken:     a pose handed over at w ─▶ a tick at max(w, last woken + MIN_TICK_GAP),
//!             and the period restarts from there (ticks follow the camera's frames)
//! ```

use std::time::{Duration, Instant};

/// The shortest time between two ticks when a camera's pose brings one forward (the highest
/// tick rate the server accepts).
pub const MIN_TICK_GAP: Duration = Duration::from_micros(1_000_000 / 240);

/// The tick's timetable.
#[derive(Debug, Clone)]
pub struct TickSchedule {
    period: Duration,
    /// The next periodic tick (`None` before the first time is known).
    periodic: Option<Instant>,
    /// A tick brought forward by a handed-over pose, when one is pending.
    woken: Option<Instant>,
    /// When the last woken tick ran.
    last_woken: Option<Instant>,
}

impl TickSchedule {
    /// Ticks every `period` (at least 1 µs), the first one at the first time it is given.
    pub fn new(period: Duration) -> TickSchedule {
        TickSchedule {
            period: period.max(Duration::from_micros(1)),
            periodic: None,
            woken: None,
            last_woken: None,
        }
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// A pose that should be taken at once was handed over at `at`: a tick then, but never
    /// closer than [`MIN_TICK_GAP`] to the last woken one (a burst of poses cannot spin the
    /// tick). A woken tick right after a periodic one does not wait: a camera at the tick
    /// rate or half of it hands its pose over about when the restarted period ends, and
    /// waiting there would be the handoff's p99.
    pub fn wake(&mut self, at: Instant) {
        let earliest = self.last_woken.map_or(at, |t| (t + MIN_TICK_GAP).max(at));
        self.woken = Some(self.woken.map_or(earliest, |w| w.min(earliest)));
    }

    /// When the next tick is due (`now` itself before the first tick).
    pub fn next(&self, now: Instant) -> Instant {
        let periodic = self.periodic.unwrap_or(now);
        self.woken.map_or(periodic, |w| w.min(periodic))
    }

    /// Whether a tick is due at `now`; if so it is taken and the timetable moves on: after a
    /// woken tick the period restarts from it, after a periodic one the next deadline is the
    /// first one still ahead (missed deadlines are skipped, not made up in a burst).
    pub fn take_due(&mut self, now: Instant) -> bool {
        if self.next(now) > now {
            return false;
        }
        if self.woken.is_some_and(|w| w <= now) {
            self.woken = None;
            self.last_woken = Some(now);
            self.periodic = Some(now + self.period);
            return true;
        }
        let deadline = self.periodic.unwrap_or(now);
        let late = now.saturating_duration_since(deadline).as_nanos();
        let period = self.period.as_nanos();
        let skip = (late / period + 1) * period;
        self.periodic = Some(deadline + Duration::from_nanos(skip.min(u64::MAX as u128) as u64));
        true
    }
}

/// Something done at a fixed interval off the tick (every `every`, the first time at once).
#[derive(Debug, Clone, Copy)]
pub struct Every {
    every: Duration,
    next: Option<Instant>,
}

impl Every {
    /// Every `every`.
    pub fn new(every: Duration) -> Every {
        Every { every, next: None }
    }

    /// When it is next due (`now` if it has never run).
    pub fn next(&self, now: Instant) -> Instant {
        self.next.unwrap_or(now)
    }

    /// Whether it is due at `now`; if so the next time is set (missed times skipped).
    pub fn take_due(&mut self, now: Instant) -> bool {
        if self.next(now) > now {
            return false;
        }
        let mut next = self.next.unwrap_or(now) + self.every;
        if next <= now {
            next = now + self.every;
        }
        self.next = Some(next);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn periodic_ticks_skip_missed_deadlines() {
        let t0 = Instant::now();
        let mut s = TickSchedule::new(10 * MS);
        assert_eq!(s.next(t0), t0);
        assert!(s.take_due(t0));
        assert!(!s.take_due(t0 + 9 * MS));
        assert_eq!(s.next(t0), t0 + 10 * MS);
        // 35 ms late: the deadlines at 20 and 30 ms are skipped, the next is 40 ms.
        assert!(s.take_due(t0 + 35 * MS));
        assert_eq!(s.next(t0), t0 + 40 * MS);
    }

    #[test]
    fn a_handed_over_pose_brings_the_tick_forward_and_restarts_the_period() {
        let t0 = Instant::now();
        let mut s = TickSchedule::new(10 * MS);
        assert!(s.take_due(t0));
        s.wake(t0 + 3 * MS);
        assert_eq!(s.next(t0), t0 + 3 * MS);
        assert!(s.take_due(t0 + 3 * MS));
        assert_eq!(s.next(t0), t0 + 13 * MS);
        // A second pose 1 ms later waits out the gap between woken ticks.
        s.wake(t0 + 4 * MS);
        assert_eq!(s.next(t0), t0 + 3 * MS + MIN_TICK_GAP);
        // A periodic tick right before a woken one does not delay it.
        let mut s = TickSchedule::new(10 * MS);
        assert!(s.take_due(t0));
        assert!(s.take_due(t0 + 10 * MS));
        s.wake(t0 + 10 * MS + MS / 2);
        assert_eq!(s.next(t0), t0 + 10 * MS + MS / 2);
    }

    #[test]
    fn every_runs_at_once_then_at_its_interval() {
        let t0 = Instant::now();
        let mut e = Every::new(50 * MS);
        assert!(e.take_due(t0));
        assert!(!e.take_due(t0 + 49 * MS));
        assert!(e.take_due(t0 + 50 * MS));
        assert!(e.take_due(t0 + 500 * MS));
        assert_eq!(e.next(t0), t0 + 550 * MS);
    }
}
