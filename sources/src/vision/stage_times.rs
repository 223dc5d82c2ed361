//! Where a camera frame's time goes, stage by stage, over the last [`WINDOW`] frames: the
//! latency figures of a camera source (`camera.stages` in `/v1/status`). Recording is a
//! fixed-size ring (no allocation per frame); the report sorts copies (status only).

use rigcast_protocol::control::StageLatency;

/// The stages, in the order of [`StageTimes::record`]'s values.
pub const STAGES: [&str; 6] = [
    "capture",
    "decode",
    "detect",
    "landmarks",
    "solve",
    "glass_to_pose",
];

/// Frames kept.
pub const WINDOW: usize = 256;

/// The last [`WINDOW`] frames' stage times, microseconds.
#[derive(Debug)]
pub struct StageTimes {
    micros: Box<[[u32; WINDOW]; STAGES.len()]>,
    next: usize,
    filled: usize,
}

impl Default for StageTimes {
    fn default() -> Self {
        StageTimes {
            micros: Box::new([[0; WINDOW]; STAGES.len()]),
            next: 0,
            filled: 0,
        }
    }
}

impl StageTimes {
    /// One frame's times, nanoseconds, in [`STAGES`] order.
    pub fn record(&mut self, nanos: [u64; STAGES.len()]) {
        for (stage, n) in nanos.iter().enumerate() {
            self.micros[stage][self.next] = (n / 1000).min(u32::MAX as u64) as u32;
        }
        self.next = (self.next + 1) % WINDOW;
        self.filled = (self.filled + 1).min(WINDOW);
    }

    /// p50 and p99 of every stage (empty before the first frame).
    pub fn report(&self) -> Vec<StageLatency> {
        if self.filled == 0 {
            return Vec::new();
        }
        STAGES
            .iter()
            .enumerate()
            .map(|(stage, name)| {
                let mut v = self.micros[stage][..self.filled].to_vec();
                v.sort_unstable();
                let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] as f32 / 1000.0;
                StageLatency {
                    stage: (*name).to_string(),
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

    #[test]
    fn percentiles_of_the_window() {
        let mut t = StageTimes::default();
        assert!(t.report().is_empty());
        for i in 1..=100u64 {
            t.record([i * 1_000_000, 0, 0, 0, 0, 2 * i * 1_000_000]);
        }
        let r = t.report();
        assert_eq!(r[0].stage, "capture");
        assert_eq!(r[0].samples, 100);
        assert!((r[0].p50_ms - 50.0).abs() <= 1.0, "{r:?}");
        assert!((r[0].p99_ms - 99.0).abs() <= 1.0, "{r:?}");
        assert!((r[5].p99_ms - 198.0).abs() <= 2.0, "{r:?}");
        // The window keeps the latest frames only.
        for _ in 0..WINDOW {
            t.record([1_000_000; 6]);
        }
        assert_eq!(t.report()[0].p99_ms, 1.0);
    }
}
