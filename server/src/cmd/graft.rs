//! `rigcast graft --upper A --lower B -o OUT`: the upper body of clip A on the legs of clip B,
//! in step (seed 002). A is retargeted onto B's rig first (any two rigs, through the
//! automatic mapping), both clips' footplants are detected on their own rigs, and A's clock is
//! warped so its landings fall on B's (`rigcast_retarget::graft`). The output is B's rig with
//! B's frame times, written onto B's own file layout like `rigcast retarget`'s outputs.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use anyhow::{anyhow, bail};
use clap::Args;
use rigcast_retarget::graft::GraftSettings;

use crate::offline::{graft_clips, Grafted};

/// Options of `rigcast graft`.
#[derive(Debug, Clone, Args)]
pub struct GraftArgs {
    /// The clip whose upper body (spine above the waist, arms, head) is taken.
    #[arg(long)]
    pub upper: PathBuf,
    /// The locomotion clip whose pelvis and legs are kept (the output is on its rig).
    #[arg(long)]
    pub lower: PathBuf,
    /// Output file (.bvh, .glb or .rcr), on the lower clip's rig.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Mapping overrides (TOML) for mapping the upper clip's rig onto the lower clip's.
    #[arg(long)]
    pub mapping: Option<PathBuf>,
    /// Spine bones over which the upper clip's rotation blends in (1 = a hard cut).
    #[arg(long, default_value_t = 3)]
    pub blend_bones: usize,
    /// Pose clusters per body half.
    #[arg(long, default_value_t = 12)]
    pub clusters: usize,
}

/// Runs the command.
pub fn run(args: &GraftArgs) -> anyhow::Result<()> {
    super::retarget::output_extension(&args.output)?;
    let upper = rigcast_sources::load_clip(&args.upper)
        .map_err(|e| anyhow!("cannot read the upper clip: {e}"))?;
    let (lower, layout) = rigcast_sources::load_rig(&args.lower)
        .map_err(|e| anyhow!("cannot read the lower clip: {e}"))?;
    for (clip, path) in [(&upper, &args.upper), (&lower, &args.lower)] {
        if clip.num_frames() < 2 {
            bail!(
                "{} has no motion to graft (fewer than 2 frames)",
                path.display()
            );
        }
    }
    if !(1..=256).contains(&args.clusters) {
        bail!("--clusters {}: expected 1 to 256", args.clusters);
    }
    let settings = GraftSettings {
        clusters: args.clusters,
        blend_bones: args.blend_bones.max(1),
    };
    let overrides = args
        .mapping
        .as_deref()
        .map(crate::boot::load::read_mapping)
        .transpose()?;
    let mut bar = Bar::new(true);
    let g = graft_clips(
        &upper,
        &lower,
        overrides.as_ref(),
        &settings,
        &mut |d, n| bar.show(d, n),
    )?;
    bar.finish();
    rigcast_sources::save_clip_onto(&args.output, &g.clip, &layout)
        .map_err(|e| anyhow!("cannot write: {e}"))?;
    print_summary(args, &g);
    Ok(())
}

fn print_summary(args: &GraftArgs, g: &Grafted) {
    let p = &g.plan;
    println!(
        "wrote {} ({} bones; {} frames at {:.3} fps)",
        args.output.display(),
        g.clip.skeleton.num_bones(),
        g.clip.num_frames(),
        g.clip.fps()
    );
    let anchor = match p.anchor {
        Some((l, u)) => format!(
            "from lower frame {l} ↔ upper frame {u}{}",
            if p.anchor_is_transition {
                ", a shared lower-body cluster"
            } else {
                ", no shared cluster at a landing: nearest poses"
            }
        ),
        None => "none to synchronise on: both play from their start".into(),
    };
    println!(
        "plants: {} landings in the upper clip, {} in the lower; {} paired ({anchor})",
        p.plants.0, p.plants.1, p.paired
    );
    let frame_secs = g.clip.frame_time_secs;
    let held = (0..g.clip.num_frames())
        .filter(|&f| p.warp.holds(f as f64 * frame_secs))
        .count();
    println!(
        "resampling: the upper clip plays at {:.3}x its speed; its end poses held for {held} frames",
        p.warp.factor()
    );
    println!(
        "clusters shared: lower body {}/{n}, upper body {}/{n}; spine blended over {} bones",
        p.shared_clusters.0,
        p.shared_clusters.1,
        g.split.blend.len(),
        n = args.clusters
    );
}

/// A progress bar on stderr: redrawn in place on a terminal, at 25 % steps otherwise.
struct Bar {
    enabled: bool,
    terminal: bool,
    shown: usize,
}

impl Bar {
    const WIDTH: usize = 30;

    fn new(enabled: bool) -> Bar {
        Bar {
            enabled,
            terminal: std::io::stderr().is_terminal(),
            shown: usize::MAX,
        }
    }

    fn show(&mut self, done: usize, total: usize) {
        if !self.enabled || total == 0 {
            return;
        }
        let steps = if self.terminal { 100 } else { 4 };
        let step = done * steps / total;
        if step == self.shown {
            return;
        }
        self.shown = step;
        let filled = done * Self::WIDTH / total;
        let bar = format!("{}{}", "#".repeat(filled), "-".repeat(Self::WIDTH - filled));
        let line = format!(
            "grafting [{bar}] {:3}% ({done}/{total} frames)",
            done * 100 / total
        );
        if self.terminal {
            eprint!("\r{line}");
        } else {
            eprintln!("{line}");
        }
        // Progress only: a closed stderr must not stop the graft.
        let _ = std::io::stderr().flush();
    }

    fn finish(&self) {
        if self.enabled && self.terminal {
            eprintln!();
        }
    }
}
