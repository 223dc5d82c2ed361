//! `rigcast retarget ANIM --target SKELETON -o OUT`: put an animation onto another character,
//! offline. The output has the source's frame count and frame time (unless `--fps` resamples);
//! any animation in the target file is replaced. Written in the target's own format, it is the
//! target's rig exactly: a BVH keeps its joint order, End Sites, channels and offsets, a GLB its
//! nodes, names, skin joint order, inverse bind matrices and meshes.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context};
use clap::Args;
use rigcast_retarget::analysis::{analyze_with_truth, standing_posture, Analysis, SkeletonView};
use rigcast_retarget::footplant::{detect_clip, FootLock, LockSettings, PlantSettings};
use rigcast_retarget::mapping::{
    apply_overrides, map_analyzed, posture_relative, MapOptions, MappingTable,
};
use rigcast_retarget::{
    BoneId, Clip, Follow, Mapping, Pose, RetargetOptions, RootMotion, Skeleton,
};

/// Options of `rigcast retarget`.
#[derive(Debug, Clone, Args)]
pub struct RetargetArgs {
    /// The animation to retarget (.bvh, .gltf/.glb, .vrm or a .rcr recording).
    pub anim: PathBuf,
    /// The character to put it on (.bvh, .gltf/.glb, .vrm, .rcr); its own animation is ignored.
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
    // Source errors already name the file and the cause; no extra context, so nothing repeats.
    let mut clip = rigcast_sources::load_clip(&args.anim)
        .map_err(|e| anyhow!("cannot read the animation: {e}"))?;
    if clip.num_frames() == 0 {
        bail!(
            "{} has no animation frames to retarget",
            args.anim.display()
        );
    }
    let (target_clip, target_layout) = rigcast_sources::load_rig(&args.target)
        .map_err(|e| anyhow!("cannot read the target character: {e}"))?;
    let target = target_clip.skeleton.clone();
    if let Some(fps) = args.fps {
        if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
            bail!("--fps {fps}: expected a frame rate between 0 and 10000");
        }
        clip = clip
            .resampled(1.0 / fps)
            .with_context(|| format!("cannot resample to {fps} fps"))?;
    }
    // A .vrm's humanoid extension is ground truth for its bones' roles.
    let truth_s = super::map::vrm_truth(&args.anim);
    let truth_t = super::map::vrm_truth(&args.target);
    let plan = plan_mapping_with_truth(
        &clip,
        &target_clip,
        args.mapping.as_deref(),
        (truth_s.as_deref(), truth_t.as_deref()),
    )?;
    // What the analysis could not read as usual (a rig whose geometry disagrees with its
    // names, sides named the other way round) explains an odd result before it is seen.
    for (which, a) in [
        ("source", &plan.source_analysis),
        ("target", &plan.target_analysis),
    ] {
        for w in &a.warnings {
            eprintln!("warning: {which}: {w}");
        }
    }
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
    let out = retarget_clip_locked(&clip, &target, table, &opts, lock, true)?;
    // Written onto the target file's own layout: a BVH keeps its hierarchy, a GLB its nodes,
    // skin and meshes.
    rigcast_sources::save_clip_onto(&args.output, &out, &target_layout)
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

/// What [`plan_mapping`] decides.
#[derive(Debug, Clone)]
pub struct MappingPlan {
    /// Target bone → source bone(s).
    pub table: MappingTable,
    /// A representative source pose when the source's rest pose is degenerate (no posture).
    pub source_reference: Option<Pose>,
    /// The same for the target (from its own animation, used for alignment only).
    pub target_reference: Option<Pose>,
    /// The source's up direction, as its analysis found it (Z-up captures exist).
    pub source_up: glam::Vec3,
    /// The source skeleton's analysis (its legs drive foot locking).
    pub source_analysis: Analysis,
    /// The target skeleton's analysis.
    pub target_analysis: Analysis,
    /// Target bones that keep their own posture and follow the source's motion from its
    /// standing posture (`mapping::posture_relative`: a walker driving a quadruped).
    pub posture_relative: Vec<(BoneId, Follow)>,
    /// The source's standing posture those bones' motion is measured from (its clip's mean
    /// posture), when there are such bones.
    pub source_standing: Option<Pose>,
}

impl MappingPlan {
    /// Options to retarget `source` (the clip this plan was made for) with this plan: its
    /// frame time, both reference postures and the source's up, with `root_motion`.
    pub fn retarget_options(&self, source: &Clip, root_motion: RootMotion) -> RetargetOptions {
        RetargetOptions {
            frame_time_secs: source.frame_time_secs as f32,
            root_motion,
            source_reference: vec![self.source_reference.clone()],
            target_reference: self.target_reference.clone(),
            posture_relative: self.posture_relative.clone(),
            source_standing: vec![self.source_standing.clone()],
            source_up: Some(self.source_up),
            ..RetargetOptions::default()
        }
    }
}

/// Maps the clip's skeleton onto the target with the automatic mapper, then applies the
/// overrides file (TOML, `retarget/MAPPING.md`) if given. Rests without a posture (all joints
/// on a line) are analysed, and aligned, on a representative frame instead.
pub fn plan_mapping(
    source: &Clip,
    target: &Clip,
    overrides: Option<&Path>,
) -> anyhow::Result<MappingPlan> {
    plan_mapping_with_truth(source, target, overrides, (None, None))
}

/// A ground-truth humanoid map (VRM human bone name → bone name), when the file has one.
pub type HumanoidTruth<'a> = Option<&'a [(String, String)]>;

/// [`plan_mapping`] with ground-truth humanoid maps (VRM: human bone name → bone name) for the
/// source and the target, which override the inferred roles of the bones they name.
pub fn plan_mapping_with_truth(
    source: &Clip,
    target: &Clip,
    overrides: Option<&Path>,
    truth: (HumanoidTruth<'_>, HumanoidTruth<'_>),
) -> anyhow::Result<MappingPlan> {
    let overrides = overrides.map(crate::boot::load::read_mapping).transpose()?;
    let (ss, ts) = (&*source.skeleton, &*target.skeleton);
    let sa = analyze_with_truth(&SkeletonView::from_clip(ss, &source.poses), truth.0);
    let ta = analyze_with_truth(&SkeletonView::from_clip(ts, &target.poses), truth.1);
    let mut table = map_analyzed(&[(ss, &sa)], (ts, &ta), &MapOptions::default());
    if let Some(file) = &overrides {
        apply_overrides(&mut table, file, &[ss], ts).context("mapping file")?;
    }
    let relative = posture_relative(&table, &[&sa], &ta);
    let source_standing = (!relative.is_empty())
        .then(|| standing_posture(ss, &source.poses, sa.up))
        .flatten();
    Ok(MappingPlan {
        posture_relative: relative,
        source_standing,
        table,
        source_up: sa.up,
        source_reference: sa.posture_pose(&source.poses),
        target_reference: ta.posture_pose(&target.poses),
        source_analysis: sa,
        target_analysis: ta,
    })
}

/// Retargets a whole clip onto `target` (floor measured over the clip), printing a percentage
/// on stderr for long clips when `progress` is set.
pub fn retarget_clip(
    clip: &Clip,
    target: &Skeleton,
    table: &MappingTable,
    opts: &RetargetOptions,
    progress: bool,
) -> anyhow::Result<Clip> {
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
    progress: bool,
) -> anyhow::Result<Clip> {
    let mut mapping = Mapping::build(&[&clip.skeleton], target, table, opts)
        .context("cannot build the retargeting mapping")?;
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
    if progress {
        if let Some((lock, plants)) = foot_lock.as_ref() {
            let found: usize = (0..plants.legs.len())
                .map(|l| plants.intervals(l).len())
                .sum();
            eprintln!(
                "foot lock: {found} plants on {} source feet, {} target feet held",
                plants.legs.len(),
                lock.target_legs().count()
            );
        }
    }
    let n = clip.num_frames();
    let report = progress && n >= PROGRESS_MIN_FRAMES;
    let mut poses = Vec::with_capacity(n);
    let mut out = mapping.new_target_pose();
    // Next percentage to print: every 5%, so the line updates a handful of times per second.
    let mut next_percent = 5;
    for (i, p) in clip.poses.iter().enumerate() {
        mapping
            .apply_one(p, &mut out)
            .with_context(|| format!("frame {i} does not fit the source skeleton"))?;
        if let Some((lock, plants)) = foot_lock.as_mut() {
            lock.apply_track(plants, i, dt, &mut out);
        }
        poses.push(out.clone());
        if report {
            let percent = (i + 1) * 100 / n;
            if percent >= next_percent {
                eprint!("\rretargeting: {percent:3}% ({}/{n} frames)", i + 1);
                // Progress only: a closed stderr must not stop the retarget.
                let _ = std::io::stderr().flush();
                next_percent = percent + 5;
            }
        }
    }
    if report {
        eprintln!();
    }
    Ok(Clip::new(
        clip.name.clone(),
        Arc::new(target.clone()),
        poses,
        clip.frame_time_secs,
    )?)
}
