//! Panic reports without a flood. A caught panic is not the end of the server (see
//! `fault.rs`): a target whose processing panics is retried every 250 ms, so a fault that
//! repeats would print the standard panic report four times a second for as long as it lasts.
//! The hook installed here prints the first report from each place in the code in full and then
//! holds back repeats from that place for [`REPEAT_WINDOW`], saying how many it held back when
//! it prints the next one. Faults are still counted and told to clients; only stderr is spared.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// How long repeats of a panic at one place are held back after a report.
pub const REPEAT_WINDOW: Duration = Duration::from_secs(60);

/// Places remembered; past this the one reported longest ago is forgotten (a panic at a new
/// place is always reported, so forgetting only ever prints more).
const MAX_PLACES: usize = 64;

/// Whether a panic's report is printed.
#[derive(Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Print it; `held_back` repeats at the same place were not printed since the last report.
    Report {
        /// Repeats not printed since the last report from this place.
        held_back: u64,
    },
    /// A repeat inside the window: count it, print nothing.
    Hold,
}

#[derive(Debug)]
struct Place {
    at: String,
    reported: Instant,
    held_back: u64,
}

/// Decides which panic reports are printed (one per place per [`REPEAT_WINDOW`]).
#[derive(Debug, Default)]
pub struct ReportLimiter {
    places: Vec<Place>,
}

impl ReportLimiter {
    /// The verdict for a panic at `at` (file:line:column) at `now`.
    pub fn admit(&mut self, at: &str, now: Instant) -> Verdict {
        if let Some(p) = self.places.iter_mut().find(|p| p.at == at) {
            if now.saturating_duration_since(p.reported) < REPEAT_WINDOW {
                p.held_back += 1;
                return Verdict::Hold;
            }
            p.reported = now;
            return Verdict::Report {
                held_back: std::mem::take(&mut p.held_back),
            };
        }
        if self.places.len() >= MAX_PLACES {
            if let Some(oldest) = (0..self.places.len()).min_by_key(|&i| self.places[i].reported) {
                self.places.swap_remove(oldest);
            }
        }
        self.places.push(Place {
            at: at.to_string(),
            reported: now,
            held_back: 0,
        });
        Verdict::Report { held_back: 0 }
    }
}

/// Installs the limiting hook in front of the current one (the standard report, or a test
/// harness's), which prints whatever is let through.
pub fn install() {
    let print = std::panic::take_hook();
    let limiter = Mutex::new(ReportLimiter::default());
    std::panic::set_hook(Box::new(move |info| {
        let at = info
            .location()
            .map(|l| format!("{}:{}:{}", l.file(), l.line(), l.column()))
            .unwrap_or_default();
        // A poisoned lock (impossible: `admit` does not panic) falls back to printing.
        let verdict = limiter
            .lock()
            .map(|mut l| l.admit(&at, Instant::now()))
            .unwrap_or(Verdict::Report { held_back: 0 });
        match verdict {
            Verdict::Hold => {}
            Verdict::Report { held_back } => {
                if held_back > 0 {
                    eprintln!(
                        "rigcast: {held_back} more panics at {at} were not printed (one report per place per {} s)",
                        REPEAT_WINDOW.as_secs()
                    );
                }
                print(info);
            }
        }
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_at_one_place_are_held_back_for_the_window_and_counted() {
        let mut l = ReportLimiter::default();
        let t0 = Instant::now();
        assert_eq!(l.admit("a.rs:1:1", t0), Verdict::Report { held_back: 0 });
        // A fault retried every 250 ms for the whole window: nothing more is printed.
        for k in 1..240 {
            let t = t0 + Duration::from_millis(250 * k);
            assert_eq!(l.admit("a.rs:1:1", t), Verdict::Hold, "repeat {k}");
        }
        // Another place is reported at once.
        assert_eq!(
            l.admit("b.rs:2:2", t0 + Duration::from_secs(1)),
            Verdict::Report { held_back: 0 }
        );
        assert_eq!(
            l.admit("a.rs:1:1", t0 + REPEAT_WINDOW),
            Verdict::Report { held_back: 239 }
        );
        assert_eq!(
            l.admit("a.rs:1:1", t0 + REPEAT_WINDOW + Duration::from_secs(1)),
            Verdict::Hold
        );
    }

    #[test]
    fn places_past_the_cap_forget_the_oldest_report() {
        let mut l = ReportLimiter::default();
        let t0 = Instant::now();
        for k in 0..MAX_PLACES as u64 + 1 {
            let at = format!("f.rs:{k}:1");
            assert_eq!(
                l.admit(&at, t0 + Duration::from_millis(k)),
                Verdict::Report { held_back: 0 }
            );
        }
        assert_eq!(l.places.len(), MAX_PLACES);
        // The first place was forgotten, so its next panic is reported again.
        assert_eq!(
            l.admit("f.rs:0:1", t0 + Duration::from_secs(1)),
            Verdict::Report { held_back: 0 }
        );
        assert_eq!(
            l.admit(&format!("f.rs:{MAX_PLACES}:1"), t0 + Duration::from_secs(1)),
            Verdict::Hold
        );
    }
}
