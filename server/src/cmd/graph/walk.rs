//! `rigcast graph walk graph.rmg --from CLIP:FRAME --to CLIP:FRAME -o out.bvh`.

use std::path::PathBuf;

use anyhow::{anyhow, bail, Context};
use clap::Args;
use rigcast_retarget::analysis::{analyze, Analysis, SkeletonView};
use rigcast_retarget::footplant::{detect_clip, FootLock, LockSettings, PlantSettings};
use rigcast_retarget::graph::play::clips_onto_rig;
use rigcast_retarget::graph::walk::shortest_walk;
use rigcast_retarget::graph::{MotionGraph, Planar, Playback, Walker};
use rigcast_retarget::mapping::MappingTable;
use rigcast_retarget::{Clip, Mapping, Pose, RetargetOptions};
use rigcast_sources::RigLayout;

use crate::graph_files::read_graph;
use crate::graph_files::{clip_spec, load_graph_clips};

/// Options of `rigcast graph walk`.
#[derive(Debug, Args)]
pub struct WalkArgs {
    /// The graph file (.rmg) from `rigcast graph build`.
    pub graph: PathBuf,
    /// Start pose: `CLIP:FRAME` (clip by number or name, frame at the graph's frame rate).
    #[arg(long)]
    pub from: String,
    /// End pose, as for --from.
    #[arg(long)]
    pub to: String,
    /// Output animation (.bvh, .glb or .rcr), on the rig of clip --rig.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Which clip's rig plays the walk (number or name; default: the --from clip's).
    #[arg(long)]
    pub rig: Option<String>,
    /// Keep wandering on the graph for this many seconds after reaching --to.
    #[arg(long, default_value_t = 0.0)]
    pub wander: f64,
    /// Seed of the wandering.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Leave the feet as blended, without pinning planted feet.
    #[arg(long)]
    pub no_foot_lock: bool,
}

/// Runs the command.
pub fn run(args: &WalkArgs) -> anyhow::Result<()> {
    if !(args.wander.is_finite() && (0.0..=3600.0).contains(&args.wander)) {
        bail!("--wander must be between 0 and 3600 seconds");
    }
    let graph = read_graph(&args.graph)?;
    let clips = load_graph_clips(&graph)?;
    let from = node(&graph, &args.from).context("--from")?;
    let to = node(&graph, &args.to).context("--to")?;
    let path = shortest_walk(&graph, from, to).map_err(|e| anyhow!("{e}"))?;
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
    let (mut poses, joins) = play(&graph, &pb, &path, extra, args.seed);
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

fn play(
    graph: &MotionGraph,
    pb: &Playback,
    path: &[usize],
    extra: usize,
    seed: u64,
) -> (Vec<Pose>, usize) {
    let mut walker = Walker::new(graph, pb, seed);
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

/// A clip by number or name.
fn clip_index(graph: &MotionGraph, s: &str) -> anyhow::Result<usize> {
    if let Ok(i) = s.parse::<usize>() {
        if i < graph.clips.len() {
            return Ok(i);
        }
        bail!(
            "clip {i} does not exist (the graph has {})",
            graph.clips.len()
        );
    }
    graph
        .clips
        .iter()
        .position(|c| c.name == s)
        .ok_or_else(|| anyhow!("no clip is named {s:?}"))
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
