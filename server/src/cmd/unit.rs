//! `--unit`: the unit a BVH file is written in, given by the user instead of guessed (a BVH
//! says nothing of its unit; the guess compares the figure's height with a person's, which a
//! dog, a crab or a giant defeats, and `rigcast info` says how sure it is).

use clap::Args;
use rigcast_sources::bvh::parse_unit;
use rigcast_sources::LoadOptions;

/// The unit of the (first) file a command reads.
#[derive(Debug, Clone, Default, Args)]
pub struct UnitArgs {
    /// BVH only: the unit the file is written in: m, dm, cm, mm, in, ft, cmu (CMU's inches /
    /// 0.45), or metres per file unit as a number (0.01). Default: guessed from the figure's
    /// height (`rigcast info` shows the guess and how sure it is). Other formats ignore it.
    #[arg(long, visible_alias = "scale", value_name = "UNIT", value_parser = parse_unit)]
    pub unit: Option<f32>,
}

impl UnitArgs {
    /// Load options reading a BVH at the given unit (guessed when none).
    pub fn load_options(&self) -> LoadOptions {
        load_options(self.unit)
    }
}

/// Load options reading a BVH at `unit` metres per file unit (guessed when `None`).
pub fn load_options(unit: Option<f32>) -> LoadOptions {
    LoadOptions {
        bvh_scale: unit,
        ..LoadOptions::default()
    }
}
