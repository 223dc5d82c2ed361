//! Reading a performer's idle graph at start: the `.rmg` file and its clips, prepared for the
//! character by the engine's `IdleGraph` (re-exported here), which walks it while the
//! performer's source is lost.

use std::path::Path;
use std::sync::Arc;

use anyhow::Context;
use rigcast_retarget::{Pose, Skeleton};

use rigcast_engine::idle_graph::IdleGraph;

/// Reads the graph file and its clips and prepares them for `target` (blocking; at
/// start). Errors name the file.
/// `stay`: the clips (names or numbers) the walk may switch into; empty: all.
pub fn load(
    path: &Path,
    target: &Arc<Skeleton>,
    target_reference: Option<&Pose>,
    tick_secs: f32,
    stay: &[String],
) -> anyhow::Result<IdleGraph> {
    let graph = crate::graph_files::read_graph(path)?;
    let within = |e: anyhow::Error| e.context(format!("idle graph {}", path.display()));
    let mask = crate::graph_files::clip_mask(&graph, stay)
        .context("idle_clips")
        .map_err(within)?;
    let clips = crate::graph_files::load_graph_clips(&graph).map_err(within)?;
    let mut idle = IdleGraph::new(&graph, &clips, target, target_reference, tick_secs)
        .map_err(|e| within(e.into()))?;
    idle.allow_clips(&mask);
    Ok(idle)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_retarget::graph::{GraphSettings, MotionGraph};
    use rigcast_retarget::Clip;

    /// On the first two labelled walks of the shared data (found by their motion), played on
    /// the mannequin: the walk never freezes and its heading frame stays where the take-over
    /// put it (the floor under the hips, within 1 mm).
    #[test]
    fn the_walk_moves_on_the_spot_it_took_over() {
        let clips: Vec<Clip> = crate::shared_data::first_walks(2)
            .into_iter()
            .map(|(_, clip, _)| clip)
            .collect();
        if clips.len() < 2 {
            println!("SKIP: fewer than two labelled walks");
            return;
        }
        let graph = MotionGraph::build(&clips, GraphSettings::default(), &mut |_| {}).unwrap();
        let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
        let mut idle = IdleGraph::new(&graph, &clips, &target, None, 1.0 / 60.0).unwrap();
        let mut shown = target.rest_pose();
        shown.translations[0].x += 0.7;
        let mut out = target.rest_pose();
        idle.take_over(&shown, &mut out);
        let spot = idle.heading(&shown).offset;
        let mut prev = out.clone();
        for tick in 0..600 {
            idle.advance(1.0 / 60.0, &mut out);
            let here = idle.heading(&out).offset;
            assert!(
                here.distance(spot) < 1e-3,
                "tick {tick}: the walk left the spot"
            );
            let turned = out
                .rotations
                .iter()
                .zip(&prev.rotations)
                .map(|(a, b)| a.angle_between(*b))
                .fold(0.0f32, f32::max);
            assert!(turned > 1e-4, "tick {tick}: frozen");
            prev.copy_from(&out);
        }
    }
}
