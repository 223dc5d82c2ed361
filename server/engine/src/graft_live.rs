//! Live grafts: a performer whose upper body comes from one source and whose lower body comes
//! from another source or from a locomotion clip looping in step (`[[performers]] upper =
//! "webcam", lower = "walk.bvh"`).
//!
//! ```text
//!  upper source ─ upper Mapping ─▶ upper on the target ─┐
//!  lower source ─┐                                      ├─ Splice (waist, spine blend) ─▶
//!  or GaitLoop ──┴ lower Mapping ─▶ lower on the target ─┘      FootLock on the lower's plants
//!   (one stride, continuous clock,                               (the clip's own plants, or
//!    travel carried on; its plant flags)                          causal detection on a source)
//! ```
//!
//! Both mappings and the splice are built by the mapper thread; the stride loop is built once
//! and survives rebuilds (a re-map after a skeleton change), so the clip's phase never jumps.
//! Per tick nothing allocates.

use std::sync::Arc;

use rigcast_retarget::analysis::Analysis;
use rigcast_retarget::footplant::{detect_clip, find_legs, FootLock, PlantSettings, MAX_FEET};
use rigcast_retarget::graft::{BodySplit, GaitLoop, GraftSettings, Half, Splice};
use rigcast_retarget::mapping::MappingTable;
use rigcast_retarget::{Clip, Mapping, Pose};

use crate::error::{failed, PrepareError, PrepareResult};

/// Where a graft's lower body comes from.
#[derive(Debug, Clone)]
pub enum LowerInput {
    /// The performer's second source subject.
    Source,
    /// A locomotion clip, looped one stride at a time.
    Clip(Arc<Clip>),
}

/// The per-tick part of a live graft (see the module doc).
#[derive(Debug)]
pub struct LiveGraft {
    /// Lower source (or the clip's skeleton) → target.
    pub lower_mapping: Mapping,
    splice: Splice,
    /// The looping stride, for a clip lower.
    pub gait: Option<GaitLoop>,
    lower_pose: Pose,
    lower_target: Pose,
    upper_target: Pose,
}

/// How the lower body's foot lock is timed this tick.
#[derive(Debug, Clone, Copy)]
pub struct LockTiming {
    /// The lower source produced a new sample since the last tick.
    pub fresh: bool,
    /// Seconds since its previous sample (a source lower) or since the last tick (a clip).
    pub dt_secs: f32,
}

impl LiveGraft {
    /// A graft on `upper`'s target: `lower_mapping` maps the lower body's skeleton (analysed as
    /// `lower_analysis`) onto it, `target` is the target's analysis; for a clip lower, `clip` is
    /// the locomotion (its stride loop and plants are made here). The foot lock, when wanted,
    /// is built on the lower mapping by the caller.
    pub fn new(
        upper: &Mapping,
        lower_mapping: Mapping,
        lower_analysis: &Analysis,
        target: &Analysis,
        clip: Option<&Clip>,
    ) -> PrepareResult<LiveGraft> {
        let skel = upper.target();
        let split = BodySplit::new(skel, target, GraftSettings::default().blend_bones)
            .map_err(failed("the character cannot be grafted"))?;
        let gait = match clip {
            Some(c) => {
                let legs = find_legs(&c.skeleton, lower_analysis);
                let plants = detect_clip(
                    &c.skeleton,
                    &legs,
                    &c.poses,
                    c.frame_time_secs as f32,
                    lower_analysis.up,
                    &PlantSettings::default(),
                );
                Some(
                    GaitLoop::new(c, &plants, lower_analysis.up)
                        .map_err(|e| PrepareError::new(format!("cannot loop {}: {e}", c.name)))?,
                )
            }
            None => None,
        };
        let lower_pose = match &gait {
            Some(g) => g.skeleton().rest_pose(),
            None => lower_mapping
                .source(0)
                .map(|s| s.rest_pose())
                .unwrap_or_else(|| skel.rest_pose()),
        };
        Ok(LiveGraft {
            splice: Splice::new(skel, split),
            lower_target: skel.rest_pose(),
            upper_target: skel.rest_pose(),
            lower_pose,
            lower_mapping,
            gait,
        })
    }

    /// The waist cut on the character.
    pub fn split(&self) -> &BodySplit {
        self.splice.split()
    }

    /// Keeps `older`'s stride clock (phase, travel) when this graft replaces it after a re-map.
    pub fn continue_from(&mut self, older: &mut LiveGraft) {
        if let (Some(new), Some(old)) = (self.gait.as_mut(), older.gait.as_mut()) {
            std::mem::swap(new, old);
        }
    }

    /// One tick: `upper_pose` through `upper`, the lower body from `lower_source` (a source
    /// lower) or the stride loop moved on by `tick_secs`, spliced into `out`, then the lower
    /// body's plants locked. Allocates nothing. False when a pose does not fit.
    pub fn apply(
        &mut self,
        upper: &mut Mapping,
        upper_pose: &Pose,
        lower_source: Option<&Pose>,
        tick_secs: f64,
        lock: Option<(&mut FootLock, LockTiming)>,
        out: &mut Pose,
    ) -> bool {
        if upper.apply(&[upper_pose], &mut self.upper_target).is_err() {
            return false;
        }
        let mut flags = [false; MAX_FEET];
        let lower = match (self.gait.as_mut(), lower_source) {
            (Some(g), _) => {
                for (f, p) in flags
                    .iter_mut()
                    .zip(g.advance(tick_secs, &mut self.lower_pose))
                {
                    *f = *p;
                }
                &self.lower_pose
            }
            (None, Some(p)) => p,
            (None, None) => return false,
        };
        if self
            .lower_mapping
            .apply(&[lower], &mut self.lower_target)
            .is_err()
        {
            return false;
        }
        if !self
            .splice
            .apply(&self.lower_target, &self.upper_target, out)
        {
            return false;
        }
        if let Some((lock, timing)) = lock {
            match self.gait {
                Some(_) => lock.apply_planted(&flags, timing.dt_secs, out),
                None => lock.apply_live(lower, timing.fresh, timing.dt_secs, out),
            }
        }
        true
    }
}

/// One table for the `mapping` message: each target bone's entry from its half's table, the
/// lower body's sources as input 1.
pub fn merged_table(upper: &MappingTable, lower: &MappingTable, split: &BodySplit) -> MappingTable {
    let mut merged = upper.clone();
    for (t, (m, l)) in merged.entries.iter_mut().zip(&lower.entries).enumerate() {
        if split.halves.get(t) == Some(&Half::Lower) {
            *m = l.clone().map(|mut e| {
                for s in &mut e.sources {
                    s.input = 1;
                }
                e
            });
        }
    }
    // Each half's flags come from the mapping that drives it.
    let lower_half =
        |b: rigcast_retarget::BoneId| split.halves.get(b.index()) == Some(&Half::Lower);
    merged.flagged.retain(|f| !lower_half(f.bone));
    merged
        .flagged
        .extend(lower.flagged.iter().filter(|f| lower_half(f.bone)).cloned());
    merged.flagged.sort_by_key(|f| f.bone);
    merged
}
