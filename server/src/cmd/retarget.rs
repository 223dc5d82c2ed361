//! `rigcast retarget ANIM --target SKELETON -o OUT`: put an animation onto another character,
//! offline. The output has the source's frame count and frame time (unless `--fps` resamples);
//! any animation in the target file is replaced. Written in the target's own format, it is the
//! target's rig exactly: a BVH keeps its joint order, End Sites, channels and offsets, a GLB its
//! nodes, names, skin joint order, inverse bind matrices and meshes.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context};
use clap::Args;
use rigcast_retarget::{Clip, RootMotion};

use crate::character::{load_character, vrm_truth, LoadedCharacter};
use crate::offline::{plan_mapping_with_truth, retarget_clip_locked, MappingPlan, Progress};

/// Options of `rigcast retarget`.
#[derive(Debug, Clone, Args)]
pub struct RetargetArgs {
    /// The animation to retarget (.bvh, .gltf/.glb, .vrm or a .rcr recording).
    pub anim: PathBuf,
    /// The character to put it on (.bvh, .gltf/.glb, .vrm, .rcr, or `builtin:mannequin`); its
    /// own animation is ignored.
    #[arg(long)]
    pub target: PathBuf,
    /// Output file (.bvh or .glb), written with the target's skeleton.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Mapping overrides (TOML) applied on top of the automatic mapping.
    #[arg(long)]
    pub mapping: Option<PathBuf>,
    /// Resample to this many frames per second (default: keep the source's frame time).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Keep the hips over the spot horizontally (walk in place).
    #[arg(long)]
    pub in_place: bool,
    /// Let the target's feet follow the retargeted legs as they are, instead of pinning each
    /// foot where it lands while the source's foot is planted.
    #[arg(long)]
    pub no_foot_lock: bool,
    /// The animation's BVH unit (instead of the guess).
    #[command(flatten)]
    pub unit: super::unit::UnitArgs,
}

/// Formats `rigcast_sources::save_clip` writes.
const OUTPUT_EXTENSIONS: [&str; 3] = ["bvh", "glb", "rcr"];

/// Clips longer than this report progress on stderr.
const PROGRESS_MIN_FRAMES: usize = 2000;

/// The output's extension, lowercased, when it is one that can be written.
pub fn output_extension(output: &Path) -> anyhow::Result<String> {
    let ext = output
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if !OUTPUT_EXTENSIONS.contains(&ext.as_str()) {
        bail!(
            "{}: cannot write .{ext} files; the output must end in .bvh, .glb or .rcr",
            output.display()
        );
    }
    Ok(ext)
}

/// Runs the command.
pub fn run(args: &RetargetArgs) -> anyhow::Result<()> {
    // Refuse an unwritable output format before doing any work.
    output_extension(&args.output)?;
    let (clip, character) = read_inputs(args)?;
    let target = character.clip.skeleton.clone();
    let overrides = args
        .mapping
        .as_deref()
        .map(crate::boot::load::read_mapping)
        .transpose()?;
    // A .vrm's humanoid extension is ground truth for its bones' roles.
    let truth_s = vrm_truth(&args.anim);
    let plan = plan_mapping_with_truth(
        &clip,
        &character.clip,
        overrides.as_ref(),
        (truth_s.as_deref(), character.truth.as_deref()),
    )?;
    print_analysis_warnings(&plan);
    let table = &plan.table;
    if table.num_mapped() == 0 {
        bail!(
            "no bone of {} could be mapped to a bone of {}",
            args.target.display(),
            args.anim.display()
        );
    }
    let motion = if args.in_place {
        RootMotion::InPlace
    } else {
        RootMotion::Scaled
    };
    let opts = plan.retarget_options(&clip, motion);
    let lock = (!args.no_foot_lock).then_some(&plan);
    let mut report = ProgressLine::default();
    let out = retarget_clip_locked(&clip, &target, table, &opts, lock, &mut |p| report.show(p))?;
    report.finish();
    // Written onto the target file's own layout: a BVH keeps its hierarchy, a GLB its nodes,
    // skin and meshes.
    rigcast_sources::save_clip_onto(&args.output, &out, &character.layout)
        .map_err(|e| anyhow!("cannot write: {e}"))?;
    println!(
        "wrote {} ({} bones, {} of them driven; {} frames at {:.3} fps)",
        args.output.display(),
        target.num_bones(),
        table.num_mapped(),
        out.num_frames(),
        out.fps()
    );
    Ok(())
}

/// The animation (resampled to `--fps` if asked) and the target character, with errors that
/// say which file is wrong.
fn read_inputs(args: &RetargetArgs) -> anyhow::Result<(Clip, LoadedCharacter)> {
    // Source errors already name the file and the cause; no extra context, so nothing repeats.
    let mut clip = rigcast_sources::load_clip_with(&args.anim, &args.unit.load_options())
        .map_err(|e| anyhow!("cannot read the animation: {e}"))?;
    if clip.num_frames() == 0 {
        bail!(
            "{} has no animation frames to retarget",
            args.anim.display()
        );
    }
    let character = load_character(&args.target)
        .map_err(|e| anyhow!("cannot read the target character: {e}"))?;
    if let Some(fps) = args.fps {
        if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
            bail!("--fps {fps}: expected a frame rate between 0 and 10000");
        }
        clip = clip
            .resampled(1.0 / fps)
            .with_context(|| format!("cannot resample to {fps} fps"))?;
    }
    Ok((clip, character))
}

/// What the analysis could not read as usual (a rig whose geometry disagrees with its names,
/// sides named the other way round) explains an odd result before it is seen.
fn print_analysis_warnings(plan: &MappingPlan) {
    for (which, a) in [
        ("source", &plan.source_analysis),
        ("target", &plan.target_analysis),
    ] {
        for w in &a.warnings {
            eprintln!("warning: {which}: {w}");
        }
    }
}

/// Progress on stderr: the foot lock's plants, then every 5 % of a long clip's frames.
#[derive(Default)]
struct ProgressLine {
    /// Next percentage to print (every 5 %, a handful of updates a second).
    next_percent: usize,
    /// Whether a percentage line was printed (and needs its newline).
    shown: bool,
}

impl ProgressLine {
    fn show(&mut self, progress: Progress) {
        match progress {
            Progress::FootLock {
                plants,
                source_feet,
                target_feet,
            } => eprintln!(
                "foot lock: {plants} plants on {source_feet} source feet, {target_feet} target feet held"
            ),
            Progress::Frames { done, total } if total >= PROGRESS_MIN_FRAMES => {
                let percent = done * 100 / total;
                if percent >= self.next_percent.max(5) {
                    eprint!("\rretargeting: {percent:3}% ({done}/{total} frames)");
                    // Progress only: a closed stderr must not stop the retarget.
                    let _ = std::io::stderr().flush();
                    self.next_percent = percent + 5;
                    self.shown = true;
                }
            }
            Progress::Frames { .. } => {}
        }
    }

    fn finish(&self) {
        if self.shown {
            eprintln!();
        }
    }
}
