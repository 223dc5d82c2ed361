//! `rigcast convert IN OUT`: load any supported animation file and save it in the format of
//! OUT's extension.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

/// Options of `rigcast convert`.
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Input file (.bvh, .gltf/.glb/.vrm, .rcr).
    pub input: PathBuf,
    /// Output file; its extension picks the format.
    pub output: PathBuf,
    /// The input's BVH unit (instead of the guess).
    #[command(flatten)]
    pub unit: super::unit::UnitArgs,
}

/// Converts.
pub fn run(args: ConvertArgs) -> anyhow::Result<()> {
    let clip = rigcast_sources::load_clip_with(&args.input, &args.unit.load_options())
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    rigcast_sources::save_clip(&args.output, &clip)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!(
        "wrote {} ({} bones, {} frames)",
        args.output.display(),
        clip.skeleton.num_bones(),
        clip.num_frames()
    );
    Ok(())
}
