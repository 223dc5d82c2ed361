//! `rigcast graph walk graph.rmg --from CLIP:FRAME [--to CLIP:FRAME [--arrive-secs T]]
//! [--wander S] [--stay CLIP,…] -o out.bvh`: the cheapest walk, a walk that arrives on time,
//! or plain wandering, played on one clip's rig.

use std::path::PathBuf;

use anyhow::{anyhow, bail, Context};
use clap::Args;
use rigcast_retarget::analysis::{analyze, Analysis, SkeletonView};
use rigcast_retarget::footplant::{detect_clip, FootLock, LockSettings, PlantSettings};
use rigcast_retarget::graph::play::clips_onto_rig;
use rigcast_retarget::graph::walk::shortest_walk;
use rigcast_retarget::graph::{timed_walk, MotionGraph, Planar, Playback, Walker};
use rigcast_retarget::mapping::MappingTable;
use rigcast_retarget::{Clip, Mapping, Pose, RetargetOptions};
use rigcast_sources::RigLayout;

use crate::graph_files::read_graph;
use crate::graph_files::{clip_index, clip_mask, clip_spec, load_graph_clips};

/// Options of `rigcast graph walk`.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  rigcast graph walk g.rmg --from walk:60 --to run:200 -o out.bvh
      the cheapest walk between the two poses
  rigcast graph walk g.rmg --from walk:60 --to run:200 --arrive-secs 12 -o out.bvh
      wander, and be at run:200 exactly 12 s after the start
  rigcast graph walk g.rmg --from idle:0 --stay idle,idle2 --wander 30 -o out.bvh
      30 s of wandering that stays in the two idle clips")]
pub struct WalkArgs {
    /// The graph file (.rmg) from `rigcast graph build`.
    pub graph: PathBuf,
    /// Start pose: `CLIP:FRAME` (clip by number or name, frame at the graph's frame rate).
    #[arg(long)]
    pub from: String,
    /// End pose, as for --from (without it the walk only wanders, for --wander seconds).
    #[arg(long)]
    pub to: Option<String>,
    /// Arrive at --to exactly this many seconds after the start (to the nearest frame):
    /// wander, then take the cheapest way in that lands on time, instead of the cheapest
    /// walk. A time shorter than the quickest walk is an error saying by how much.
    #[arg(long, value_name = "SECS", requires = "to")]
    pub arrive_secs: Option<f64>,
    /// Output animation (.bvh, .glb or .rcr), on the rig of clip --rig.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Which clip's rig plays the walk (number or name; default: the --from clip's).
    #[arg(long)]
    pub rig: Option<String>,
    /// Keep wandering on the graph for this many seconds after reaching --to (without --to:
    /// from --from).
    #[arg(long, default_value_t = 0.0)]
    pub wander: f64,
    /// Wander only into these clips (numbers or names, comma-separated): the walk switches
    /// clips by choice only into them, and leaves them only when a clip ends with no other
    /// way on (with --arrive-secs: not in its last stretch, the cheapest way in on time).
    #[arg(long, value_name = "CLIP[,CLIP…]", value_delimiter = ',')]
    pub stay: Vec<String>,
    /// Seed of the wandering.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Leave the feet as blended, without pinning planted feet.
    #[arg(long)]
    pub no_foot_lock: bool,
}

/// Runs the command.
pub fn run(args: &WalkArgs) -> anyhow::Result<()> {
    for (name, v) in [
        ("--wander", Some(args.wander)),
        ("--arrive-secs", args.arrive_secs),
    ] {
        if v.is_some_and(|v| !(v.is_finite() && (0.0..=3600.0).contains(&v))) {
            bail!("{name} must be between 0 and 3600 seconds");
        }
    }
    if args.to.is_none() && args.wander <= 0.0 {
        bail!("without --to there is nothing to walk to: give --to, or --wander SECS");
    }
    let graph = read_graph(&args.graph)?;
    let clips = load_graph_clips(&graph)?;
    let from = node(&graph, &args.from).context("--from")?;
    let stay = clip_mask(&graph, &args.stay).context("--stay")?;
    let path = walk_path(&graph, args, from, &stay)?;
    let rig_index = match &args.rig {
        Some(r) => clip_index(&graph, r).context("--rig")?,
        None => graph.locate(from).map(|(c, _)| c).unwrap_or(0),
    };
    let rig_spec = clip_spec(&graph, rig_index)?;
    let (_, layout) = rigcast_sources::load_rig(&rig_spec.path).map_err(|e| anyhow!("{e}"))?;
    let rig = &clips[rig_index];
    let analysis = analyze(&SkeletonView::from_clip(&rig.skeleton, &rig.poses));
    let played = clips_onto_rig(&clips, rig).map_err(|e| anyhow!("{e}"))?;
    let pb = Playback::new(&graph, &played, &analysis).map_err(|e| anyhow!("{e}"))?;
    let extra = (args.wander / graph.frame_time_secs).round() as usize;
    let (mut poses, joins) = play(&graph, &pb, &path, extra, args.seed, &stay);
    if !args.no_foot_lock {
        lock_feet(&pb, &analysis, &mut poses);
    }
    let clip = Clip::new("walk", pb.skeleton().clone(), poses, graph.frame_time_secs)
        .map_err(|e| anyhow!("{e}"))?;
    save(&args.output, &clip, &layout)?;
    eprintln!(
        "walk: {} frames ({:.2} s), {} transitions → {}",
        clip.num_frames(),
        clip.duration_secs(),
        joins,
        args.output.display()
    );
    Ok(())
}

/// The nodes to follow before wandering: the cheapest walk to --to, the timed one, or just
/// the start.
fn walk_path(
    graph: &MotionGraph,
    args: &WalkArgs,
    from: usize,
    stay: &[bool],
) -> anyhow::Result<Vec<usize>> {
    let Some(to) = &args.to else {
        return Ok(vec![from]);
    };
    let to = node(graph, to).context("--to")?;
    let Some(secs) = args.arrive_secs else {
        return shortest_walk(graph, from, to).map_err(|e| anyhow!("{e}"));
    };
    let frames = (secs / graph.frame_time_secs).round() as usize;
    let walk = timed_walk(graph, from, to, frames, args.seed, stay).map_err(|e| anyhow!("{e}"))?;
    let at = |f: usize| f as f64 * graph.frame_time_secs;
    if walk.arrival_frame() == frames {
        eprintln!(
            "walk: arrives at {} at {:.3} s (frame {frames}; the quickest walk takes {:.3} s)",
            args.to.as_deref().unwrap_or_default(),
            at(frames),
            at(walk.quickest_frames)
        );
    } else {
        eprintln!(
            "walk: no walk through the graph takes exactly {:.3} s; the nearest arrives at \
             {:.3} s ({:+} frames)",
            at(frames),
            at(walk.arrival_frame()),
            walk.arrival_frame() as i64 - frames as i64
        );
    }
    Ok(walk.nodes)
}

fn play(
    graph: &MotionGraph,
    pb: &Playback,
    path: &[usize],
    extra: usize,
    seed: u64,
    stay: &[bool],
) -> (Vec<Pose>, usize) {
    let mut walker = Walker::new(graph, pb, seed);
    walker.set_allowed_clips(stay);
    walker.follow(path, Planar::IDENTITY);
    let mut out = pb.skeleton().rest_pose();
    walker.write(pb, &mut out);
    let mut poses = vec![out.clone()];
    for _ in 1..path.len() + extra {
        walker.step(pb, &mut out);
        poses.push(out.clone());
    }
    (poses, walker.transitions_taken)
}

/// Pins planted feet of the walk (plants detected on the walk itself, two-sided) with the
/// foot lock, on the rig mapped onto itself.
fn lock_feet(pb: &Playback, analysis: &Analysis, poses: &mut [Pose]) {
    let skel = pb.skeleton();
    let table = MappingTable::by_exact_name(skel, skel);
    let Ok(mapping) = Mapping::build(&[skel], skel, &table, &RetargetOptions::default()) else {
        return;
    };
    let Some(mut lock) = FootLock::new(&mapping, analysis, analysis, LockSettings::default())
    else {
        return;
    };
    let dt = pb.frame_time_secs() as f32;
    let plants = detect_clip(
        skel,
        lock.source_legs(),
        poses,
        dt,
        pb.up(),
        &PlantSettings::default(),
    );
    for (i, p) in poses.iter_mut().enumerate() {
        lock.apply_planted(plants.frame(i), dt, p);
    }
}

fn save(path: &std::path::Path, clip: &Clip, layout: &RigLayout) -> anyhow::Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let onto = matches!(
        (ext.as_str(), layout),
        ("bvh", RigLayout::Bvh(_)) | ("glb", RigLayout::Gltf(_))
    );
    let r = if onto {
        rigcast_sources::save_clip_onto(path, clip, layout)
    } else {
        rigcast_sources::save_clip(path, clip)
    };
    r.map_err(|e| anyhow!("{e}"))
}

/// `CLIP:FRAME` → a global node.
fn node(graph: &MotionGraph, s: &str) -> anyhow::Result<usize> {
    let (clip, frame) = s
        .rsplit_once(':')
        .ok_or_else(|| anyhow!("{s:?} is not CLIP:FRAME"))?;
    let c = clip_index(graph, clip)?;
    let f: usize = frame
        .parse()
        .map_err(|_| anyhow!("{frame:?} is not a frame number"))?;
    let meta = &graph.clips[c];
    if f >= meta.frames {
        bail!("clip {c} has {} frames; {f} is past its end", meta.frames);
    }
    let n = meta.offset + f;
    if !graph.is_kept(n) {
        bail!("frame {f} of clip {c} was pruned (not connected); try a neighbouring frame");
    }
    Ok(n)
}
