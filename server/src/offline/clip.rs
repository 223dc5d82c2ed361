//! Whole clips retargeted onto a character, the feet locked where the source's stand.

use std::sync::Arc;

use rigcast_retarget::footplant::{detect_clip, FootLock, LockSettings, PlantSettings};
use rigcast_retarget::mapping::MappingTable;
use rigcast_retarget::{Clip, Mapping, RetargetOptions, Skeleton};

use super::{MappingPlan, OfflineError};

/// What [`retarget_clip_locked`] reports while it works.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// The foot lock is set up: plants found on the source's feet, target feet it holds.
    FootLock {
        /// plants found over the clip, all feet together
        plants: usize,
        /// the source's feet
        source_feet: usize,
        /// the target's feet the lock holds
        target_feet: usize,
    },
    /// `done` of `total` frames retargeted.
    Frames {
        /// frames done
        done: usize,
        /// frames in the clip
        total: usize,
    },
}

/// Retargets a whole clip onto `target` (floor measured over the clip), reporting to
/// `progress`.
pub fn retarget_clip(
    clip: &Clip,
    target: &Skeleton,
    table: &MappingTable,
    opts: &RetargetOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<Clip, OfflineError> {
    retarget_clip_locked(clip, target, table, opts, None, progress)
}

/// [`retarget_clip`], with the target's feet locked while the source's are planted (plants
/// detected over the whole clip, two-sided) when `lock` gives both skeletons' analyses. A
/// target without standing legs is retargeted unlocked.
pub fn retarget_clip_locked(
    clip: &Clip,
    target: &Skeleton,
    table: &MappingTable,
    opts: &RetargetOptions,
    lock: Option<&MappingPlan>,
    progress: &mut dyn FnMut(Progress),
) -> Result<Clip, OfflineError> {
    let mut mapping =
        Mapping::build(&[&clip.skeleton], target, table, opts).map_err(OfflineError::Build)?;
    if opts.source_floor_y.is_none() {
        if let Some(floor) = mapping.measure_source_floor(&clip.poses) {
            mapping.set_source_floor_y(floor);
        }
    }
    let dt = clip.frame_time_secs as f32;
    let mut foot_lock = lock.and_then(|plan| {
        let mut lock = FootLock::new(
            &mapping,
            &plan.source_analysis,
            &plan.target_analysis,
            LockSettings::default(),
        )?;
        let plants = detect_clip(
            &clip.skeleton,
            lock.source_legs(),
            &clip.poses,
            dt,
            plan.source_analysis.up,
            &PlantSettings::default(),
        );
        if let Ok(animated) = mapping.clone().apply_clip(clip) {
            lock.fit_to_standing(&animated.poses, &plants);
        }
        Some((lock, plants))
    });
    if let Some((lock, plants)) = foot_lock.as_ref() {
        progress(Progress::FootLock {
            plants: (0..plants.legs.len())
                .map(|l| plants.intervals(l).len())
                .sum(),
            source_feet: plants.legs.len(),
            target_feet: lock.target_legs().count(),
        });
    }
    let total = clip.num_frames();
    let mut poses = Vec::with_capacity(total);
    let mut out = mapping.new_target_pose();
    for (i, p) in clip.poses.iter().enumerate() {
        mapping
            .apply_one(p, &mut out)
            .map_err(|source| OfflineError::Frame { index: i, source })?;
        if let Some((lock, plants)) = foot_lock.as_mut() {
            lock.apply_track(plants, i, dt, &mut out);
        }
        poses.push(out.clone());
        progress(Progress::Frames { done: i + 1, total });
    }
    Ok(Clip::new(
        clip.name.clone(),
        Arc::new(target.clone()),
        poses,
        clip.frame_time_secs,
    )?)
}
