//! Fixed, documented benchmark workloads (used by `retarget/benches/retarget.rs` and
//! `rigcast bench`), built in code so every machine measures the same thing:
//!
//! - [`humanoid_from_cmu`]: the procedural 65-bone Mixamo-style humanoid (with fingers) driven
//!   by its 31-bone CMU (cgspeed) convention;
//! - [`creature_from_humanoid`]: the procedural 187-bone dragon-like creature driven by the
//!   65-bone humanoid;
//!
//! both mapped by the automatic mapper (at setup, not timed), fed [`walk`]: a deterministic
//! 120-frame procedural motion.

use glam::{Quat, Vec3};

use crate::analysis::SkeletonView;
use crate::mapping::{auto_map, MapOptions, MappingTable};
use crate::pose::Pose;
use crate::procedural::{creatures, humanoid, Style};
use crate::skeleton::Skeleton;
use crate::{Mapping, RetargetError, RetargetOptions};

/// A deterministic walk-like motion: every bone swings about its own axis with its own phase,
/// the root travels forward and bobs.
pub fn walk(skeleton: &Skeleton, num_frames: usize) -> Vec<Pose> {
    let rest = skeleton.rest_pose();
    (0..num_frames)
        .map(|f| {
            let t = f as f32 / 60.0;
            let mut p = rest.clone();
            for (i, r) in p.rotations.iter_mut().enumerate() {
                let k = i as f32;
                let axis = Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), 0.5).normalize_or_zero();
                *r = rest.rotations[i] * Quat::from_axis_angle(axis, 0.4 * (3.0 * t + k).sin());
            }
            p.translations[0] += Vec3::new(0.0, 0.03 * (6.0 * t).sin(), 1.3 * t);
            p
        })
        .collect()
}

/// A source, a target, a mapping table and source poses.
#[derive(Debug, Clone)]
pub struct Workload {
    /// Source skeleton.
    pub source: Skeleton,
    /// Target skeleton.
    pub target: Skeleton,
    /// Target → source table.
    pub table: MappingTable,
    /// Source poses to feed.
    pub poses: Vec<Pose>,
}

impl Workload {
    /// The workload's mapping with default options (what every bench drives).
    pub fn mapping(&self) -> Result<Mapping, RetargetError> {
        Mapping::build(
            &[&self.source],
            &self.target,
            &self.table,
            &RetargetOptions::default(),
        )
    }

    /// Every source pose retargeted by `mapping` (inputs for benches of later stages).
    pub fn retargeted(&self, mapping: &mut Mapping) -> Result<Vec<Pose>, RetargetError> {
        self.poses
            .iter()
            .map(|p| {
                let mut out = mapping.new_target_pose();
                mapping.apply_one(p, &mut out)?;
                Ok(out)
            })
            .collect()
    }
}

fn workload(source: Skeleton, target: Skeleton) -> Workload {
    let table = auto_map(
        &SkeletonView::rest(&source),
        &SkeletonView::rest(&target),
        &MapOptions::default(),
    );
    let poses = walk(&source, 120);
    Workload {
        source,
        target,
        table,
        poses,
    }
}

/// 65-bone humanoid ← 31-bone CMU skeleton. `None` only if a skeleton fails to build.
pub fn humanoid_from_cmu() -> Option<Workload> {
    let (source, _) = humanoid(Style::CmuCgspeed, false).build()?;
    let (target, _) = humanoid(Style::Mixamo, true).build()?;
    Some(workload(source, target))
}

/// 187-bone creature ← 65-bone humanoid. `None` only if a skeleton fails to build.
pub fn creature_from_humanoid() -> Option<Workload> {
    let (source, _) = humanoid(Style::Mixamo, true).build()?;
    let (target, _) = creatures::dragon().build()?;
    Some(workload(source, target))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workloads_have_their_documented_sizes() {
        let w = humanoid_from_cmu().expect("corpus");
        assert_eq!((w.source.num_bones(), w.target.num_bones()), (31, 65));
        assert!(w.table.num_mapped() >= 20, "{}", w.table.num_mapped());
        let c = creature_from_humanoid().expect("corpus");
        assert_eq!((c.source.num_bones(), c.target.num_bones()), (65, 187));
        assert!(c.table.num_mapped() >= 40, "{}", c.table.num_mapped());
        println!(
            "mapped: humanoid {} / 65, creature {} / 187",
            w.table.num_mapped(),
            c.table.num_mapped()
        );
    }
}
