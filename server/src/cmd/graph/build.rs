//! `rigcast graph build CLIPS… -o graph.rmg`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Args;
use rigcast_retarget::graph::{clip_fingerprint, GraphSettings, MotionGraph};

use crate::graph_files::ClipSpec;

/// Options of `rigcast graph build`.
#[derive(Debug, Args)]
pub struct BuildArgs {
    /// Clips: `FILE` (.bvh, .glb, .gltf, .vrm, .rcr) or `FILE#ANIMATION` for one animation of
    /// a glTF file. Resampled to the first clip's frame rate.
    #[arg(required = true)]
    pub clips: Vec<String>,
    /// The graph file to write (.rmg).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Similarity threshold: RMS distance per body point over the window, in leg lengths.
    #[arg(long)]
    pub threshold: Option<f32>,
    /// Cross-fade at transitions, seconds.
    #[arg(long)]
    pub blend: Option<f32>,
    /// Build even when the cache holds this graph.
    #[arg(long)]
    pub no_cache: bool,
}

/// Runs the command.
pub fn run(args: &BuildArgs) -> anyhow::Result<()> {
    let specs: Vec<ClipSpec> = args.clips.iter().map(|s| ClipSpec::parse(s)).collect();
    let clips = specs
        .iter()
        .map(ClipSpec::load)
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut settings = GraphSettings::default();
    if let Some(t) = args.threshold {
        settings.threshold = t;
    }
    if let Some(b) = args.blend {
        settings.blend_secs = b;
    }
    let key = cache_key(&clips, &settings);
    let cached = (!args.no_cache).then(|| read_cached(&key)).flatten();
    let started = Instant::now();
    let mut graph = match cached {
        Some(g) => {
            eprintln!("graph: from the cache ({key})");
            g
        }
        None => {
            let g = MotionGraph::build(&clips, settings, &mut progress_bar)
                .map_err(|e| anyhow::anyhow!("cannot build the graph: {e}"))?;
            eprintln!();
            write_cached(&key, &g);
            g
        }
    };
    for (c, spec) in graph.clips.iter_mut().zip(&specs) {
        c.path = Some(spec.to_text());
    }
    if graph.num_kept() == 0 {
        bail!("no frames stayed connected; try a larger --threshold");
    }
    std::fs::write(&args.output, graph.to_json())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    eprintln!(
        "graph: {} nodes ({} kept), {} edges, {} transitions in {:.2} s → {}",
        graph.num_frames(),
        graph.num_kept(),
        graph.num_edges(),
        graph.transitions.len(),
        started.elapsed().as_secs_f64(),
        args.output.display()
    );
    Ok(())
}

/// A bar on stderr, redrawn in place.
fn progress_bar(done: f32) {
    const WIDTH: usize = 30;
    let filled = ((done.clamp(0.0, 1.0) * WIDTH as f32) as usize).min(WIDTH);
    eprint!(
        "\rbuilding graph [{}{}] {:3.0}%",
        "#".repeat(filled),
        " ".repeat(WIDTH - filled),
        done * 100.0
    );
    // Progress only: a closed stderr must not stop the build.
    let _ = std::io::stderr().flush();
}

/// The clips' fingerprints and the settings, hashed (FNV-1a): the cache file's name.
fn cache_key(clips: &[rigcast_retarget::Clip], settings: &GraphSettings) -> String {
    let mut text = String::new();
    for c in clips {
        text.push_str(&format!("{:016x};", clip_fingerprint(c)));
    }
    text.push_str(&serde_json::to_string(settings).unwrap_or_default());
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!(
        "{h:016x}-v{}-f{}",
        rigcast_retarget::graph::file::VERSION,
        rigcast_retarget::graph::features::FEATURES_VERSION
    )
}

fn read_cached(key: &str) -> Option<MotionGraph> {
    let path = default_cache_dir()?.join(format!("{key}.rmg"));
    MotionGraph::from_json(&std::fs::read_to_string(path).ok()?).ok()
}

fn write_cached(key: &str, graph: &MotionGraph) {
    let Some(dir) = default_cache_dir() else {
        return;
    };
    // A cache that cannot be written only costs the next build its time.
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join(format!("{key}.rmg")), graph.to_json());
    }
}

/// The graph cache: `$XDG_CACHE_HOME/rigcast/graphs`, else `~/.cache/rigcast/graphs`.
fn default_cache_dir() -> Option<PathBuf> {
    crate::dirs::rigcast_dir(crate::dirs::UserBase::Cache, "graphs")
}
