//! Where a frame's time goes, stage by stage, over the last [`WINDOW`] frames: the latency
//! figures of `/v1/status` (a camera's `camera.stages`, a subject's `latency`). Recording is a
//! fixed-size ring per stage (no allocation per frame); the report sorts copies (status only).

use crate::control::StageLatency;

/// Frames kept per stage.
pub const WINDOW: usize = 256;

/// The last [`WINDOW`] times of each of `N` stages, microseconds. Stages may be recorded
/// together ([`StageTimes::record`]) or one at a time ([`StageTimes::record_stage`]) when
/// they are measured in different places.
#[derive(Debug)]
pub struct StageTimes<const N: usize> {
    micros: Box<[[u32; WINDOW]; N]>,
    next: [usize; N],
    filled: [usize; N],
}

impl<const N: usize> Default for StageTimes<N> {
    fn default() -> Self {
        StageTimes {
            micros: Box::new([[0; WINDOW]; N]),
            next: [0; N],
            filled: [0; N],
        }
    }
}

impl<const N: usize> StageTimes<N> {
    /// One frame's times of every stage, nanoseconds.
    pub fn record(&mut self, nanos: [u64; N]) {
        for (stage, n) in nanos.into_iter().enumerate() {
            self.record_stage(stage, n);
        }
    }

    /// One frame's time of one stage (ignored past `N`), nanoseconds.
    pub fn record_stage(&mut self, stage: usize, nanos: u64) {
        if stage >= N {
            return;
        }
        let at = self.next[stage];
        self.micros[stage][at] = (nanos / 1000).min(u64::from(u32::MAX)) as u32;
        self.next[stage] = (at + 1) % WINDOW;
        self.filled[stage] = (self.filled[stage] + 1).min(WINDOW);
    }

    /// p50 and p99 of every stage measured at least once, named by `names`.
    pub fn report(&self, names: &[&str; N]) -> Vec<StageLatency> {
        (0..N)
            .filter(|&stage| self.filled[stage] > 0)
            .map(|stage| {
                let mut v = self.micros[stage][..self.filled[stage]].to_vec();
                v.sort_unstable();
                let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] as f32 / 1000.0;
                StageLatency {
                    stage: names[stage].to_string(),
                    p50_ms: at(0.5),
                    p99_ms: at(0.99),
                    samples: v.len() as u32,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NAMES: [&str; 3] = ["capture", "decode", "glass_to_pose"];

    #[test]
    fn percentiles_of_the_window() {
        let mut t = StageTimes::<3>::default();
        assert!(t.report(&NAMES).is_empty());
        for i in 1..=100u64 {
            t.record([i * 1_000_000, 0, 2 * i * 1_000_000]);
        }
        let r = t.report(&NAMES);
        assert_eq!(r[0].stage, "capture");
        assert_eq!(r[0].samples, 100);
        assert!((r[0].p50_ms - 50.0).abs() <= 1.0, "{r:?}");
        assert!((r[0].p99_ms - 99.0).abs() <= 1.0, "{r:?}");
        assert!((r[2].p99_ms - 198.0).abs() <= 2.0, "{r:?}");
        // The window keeps the latest frames only.
        for _ in 0..WINDOW {
            t.record([1_000_000; 3]);
        }
        assert_eq!(t.report(&NAMES)[0].p99_ms, 1.0);
    }

    #[test]
    fn stages_recorded_apart_report_their_own_counts() {
        let mut t = StageTimes::<3>::default();
        for _ in 0..10 {
            t.record_stage(1, 4_000_000);
        }
        t.record_stage(2, 9_000_000);
        t.record_stage(7, 1);
        let r = t.report(&NAMES);
        // A stage never measured is left out rather than reported as zero.
        assert_eq!(r.len(), 2, "{r:?}");
        assert_eq!((r[0].stage.as_str(), r[0].samples), ("decode", 10));
        assert_eq!(r[0].p99_ms, 4.0);
        assert_eq!((r[1].stage.as_str(), r[1].samples), ("glass_to_pose", 1));
    }
}
