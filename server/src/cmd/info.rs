//! `rigcast info FILE`: format, bone tree, bone count, height, frame rate, duration and
//! animations of a file (the description comes from `rigcast_sources::describe`).

use std::path::PathBuf;

use clap::Args;

/// Options of `rigcast info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The file to describe.
    pub file: PathBuf,
    /// The BVH unit (instead of the guess).
    #[command(flatten)]
    pub unit: super::unit::UnitArgs,
}

/// Prints the description.
pub fn run(args: InfoArgs) -> anyhow::Result<()> {
    let info = rigcast_sources::describe_with(&args.file, &args.unit.load_options())?;
    print!("{info}");
    Ok(())
}
