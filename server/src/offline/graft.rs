//! One clip's upper body on another clip's legs, in step (seed 002, `retarget/GRAFTING.md`).

use rigcast_retarget::analysis::Analysis;
use rigcast_retarget::footplant::{detect_clip, find_legs, PlantSettings, PlantTrack};
use rigcast_retarget::graft::{self, BodySplit, GraftPlan, GraftSettings};
use rigcast_retarget::mapping::MappingFile;
use rigcast_retarget::{Clip, RootMotion};

use super::{plan_mapping, retarget_clip, OfflineError};

/// A finished graft and how it was made.
#[derive(Debug, Clone)]
pub struct Grafted {
    /// The output clip, on the lower clip's rig.
    pub clip: Clip,
    /// The upper clip retarget onto the lower clip's rig (its own timeline).
    pub upper_on_lower: Clip,
    /// Plants, pairing, warp and shared clusters.
    pub plan: GraftPlan,
    /// The cut.
    pub split: BodySplit,
}

/// Grafts `upper`'s upper body onto `lower`: `upper` is retargeted onto `lower`'s rig (with
/// `overrides` over the automatic mapping), both clips' plants are detected on their own
/// rigs, and `upper`'s clock is warped so its landings fall on `lower`'s. `progress` is told
/// the frames synthesised (done, total).
pub fn graft_clips(
    upper: &Clip,
    lower: &Clip,
    overrides: Option<&MappingFile>,
    settings: &GraftSettings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Grafted, OfflineError> {
    let plan = plan_mapping(upper, lower, overrides)?;
    if plan.table.num_mapped() == 0 {
        return Err(OfflineError::NothingMapped {
            target: "the lower clip's rig",
            source_name: "the upper clip's",
        });
    }
    let opts = plan.retarget_options(upper, RootMotion::InPlace);
    let upper_on_lower = retarget_clip(upper, &lower.skeleton, &plan.table, &opts, &mut |_| {})
        .map_err(|e| OfflineError::GraftRetarget(Box::new(e)))?;
    let upper_plants = plants(upper, &plan.source_analysis);
    let lower_plants = plants(lower, &plan.target_analysis);
    let split = BodySplit::new(&lower.skeleton, &plan.target_analysis, settings.blend_bones)
        .map_err(OfflineError::GraftRig)?;
    let gplan = graft::plan(
        (&upper_on_lower, &upper_plants),
        (lower, &lower_plants),
        &split,
        settings,
    )?;
    let clip = graft::synthesize(&gplan, &upper_on_lower, lower, &split, progress)?;
    Ok(Grafted {
        clip,
        upper_on_lower,
        plan: gplan,
        split,
    })
}

/// Two-sided plants of a clip on its own rig.
pub fn plants(clip: &Clip, analysis: &Analysis) -> PlantTrack {
    detect_clip(
        &clip.skeleton,
        &find_legs(&clip.skeleton, analysis),
        &clip.poses,
        clip.frame_time_secs as f32,
        analysis.up,
        &PlantSettings::default(),
    )
}
