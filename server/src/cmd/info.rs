//! `rigcast info FILE`: bone tree, bone count, height, frame rate and duration of a file.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use rigcast_retarget::{world_transforms, Clip};

/// Options of `rigcast info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The file to describe.
    pub file: PathBuf,
}

/// Prints the description.
pub fn run(args: InfoArgs) -> anyhow::Result<()> {
    let clip = rigcast_sources::load_clip(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    print!("{}", describe_clip(&clip));
    Ok(())
}

/// Human-readable description of a clip.
pub fn describe_clip(clip: &Clip) -> String {
    use std::fmt::Write;
    let skel = &clip.skeleton;
    let mut out = String::new();
    let world = world_transforms(skel, &skel.rest_pose());
    let (lo, hi) = world.iter().fold((f32::MAX, f32::MIN), |(lo, hi), w| {
        (lo.min(w.translation.y), hi.max(w.translation.y))
    });
    let _ = writeln!(out, "name:      {}", clip.name);
    let _ = writeln!(out, "bones:     {}", skel.num_bones());
    let _ = writeln!(
        out,
        "height:    {:.3} m (rest pose, lowest to highest joint)",
        hi - lo
    );
    let _ = writeln!(out, "frames:    {}", clip.num_frames());
    let _ = writeln!(out, "rate:      {:.3} fps", clip.fps());
    let _ = writeln!(out, "duration:  {:.3} s", clip.duration_secs());
    let _ = writeln!(out, "fingerprint: {}", skel.fingerprint_hex());
    let _ = writeln!(out, "bone tree:");
    for b in skel.bone_ids() {
        let _ = writeln!(out, "  {}{}", "  ".repeat(skel.depth(b)), skel.name(b));
    }
    out
}
