//! `rigcast graph info graph.rmg`.

use std::path::PathBuf;

use clap::Args;

use crate::graph_files::read_graph;

/// Options of `rigcast graph info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The graph file (.rmg).
    pub graph: PathBuf,
}

/// Runs the command.
pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let g = read_graph(&args.graph)?;
    let percent = 100.0 * g.num_kept() as f64 / g.num_frames().max(1) as f64;
    println!("frame rate:   {:.2} fps", 1.0 / g.frame_time_secs);
    println!(
        "nodes:        {} frames, {} kept ({percent:.1} %)",
        g.num_frames(),
        g.num_kept()
    );
    println!(
        "edges:        {} ({} transitions)",
        g.num_edges(),
        g.transitions.len()
    );
    println!(
        "components:   {} before pruning, the largest kept",
        g.components
    );
    println!("threshold:    {} leg lengths", g.settings.threshold);
    for (i, c) in g.clips.iter().enumerate() {
        let kept = (c.offset..c.offset + c.frames)
            .filter(|&n| g.is_kept(n))
            .count();
        println!(
            "clip {i}: {} — {kept} / {} frames kept (nodes {}..{})",
            c.name,
            c.frames,
            c.offset,
            c.offset + c.frames
        );
    }
    Ok(())
}
