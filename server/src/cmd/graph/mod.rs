//! `rigcast graph build|walk|info`: motion graphs offline (issue 14). `build` reads clips and
//! writes a `.rmg` file (format in `retarget/GRAPH.md`), cached by the clips' fingerprints;
//! `walk` animates the cheapest walk between two frames, or one that arrives at a set time
//! (then, optionally, wanders, optionally inside chosen clips) and writes it as BVH on one
//! clip's rig; `info` prints the graph's size and components.

mod build;
mod info;
mod walk;

use clap::{Args, Subcommand};

/// Options of `rigcast graph`.
#[derive(Debug, Args)]
pub struct GraphArgs {
    /// What to do.
    #[command(subcommand)]
    pub action: GraphAction,
}

/// `rigcast graph` actions.
#[derive(Debug, Subcommand)]
pub enum GraphAction {
    /// Build a graph from clips (`FILE` or `FILE#ANIMATION` for glTF) into a .rmg file.
    Build(build::BuildArgs),
    /// Animate a walk from a frame (`CLIP:FRAME`, CLIP a number or name): the cheapest to
    /// another frame, one that arrives there at a set time, or wandering (optionally kept in
    /// chosen clips).
    Walk(walk::WalkArgs),
    /// Print nodes, edges, transitions and components of a .rmg file.
    Info(info::InfoArgs),
}

/// Runs `rigcast graph`.
pub fn run(args: &GraphArgs) -> anyhow::Result<()> {
    match &args.action {
        GraphAction::Build(a) => build::run(a),
        GraphAction::Walk(a) => walk::run(a),
        GraphAction::Info(a) => info::run(a),
    }
}
