//! Motion graphs on real capture (`../shared/data`; skipped with a message when absent):
//!
//! - `graph_build_10k_frames`: the whole build (analysis, features, pruned search, SCC) of a
//!   10,160-frame, 120 Hz database: the CMU walk, walk and run captures and the PyMO walk,
//!   each at four playback speeds (0.85×, 0.95×, 1.05×, 1.15×, resampled back to 120 Hz) —
//!   like several takes of the same moves;
//! - `graph_search_exhaustive_2508_frames` (the baseline): the naive all-pairs search at full
//!   resolution over the 2,508 frames of the four clips at 1× (the 10k database would take
//!   16× as long: O(N²));
//! - `graph_walk_step`: one frame of a wandering walker on the 10k graph, played on the
//!   31-joint CMU rig (the live fallback's per-tick cost).

use std::path::Path;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::graph::play::clips_onto_rig;
use rigcast_retarget::graph::search::{find_similar_exhaustive, SearchParams};
use rigcast_retarget::graph::{GraphSettings, MotionGraph, Playback, Walker};
use rigcast_retarget::Clip;
use rigcast_sources::load_clip;

const CLIPS: [&str; 4] = [
    "bvh/cmu_131_01_walk.bvh",
    "bvh/cmu_31joint_example.bvh",
    "bvh/cmu_run.bvh",
    "zoo/bvh/sparse_spine_head__pymo_meredith.bvh",
];

#[path = "../tests/common/graph_features.rs"]
mod graph_features;
#[path = "../tests/common/shared_data.rs"]
mod shared_data;

/// `clip` played at `speed`, resampled back to its frame time.
fn at_speed(clip: &Clip, speed: f64) -> Clip {
    let mut c = clip.clone();
    c.frame_time_secs /= speed;
    c.resampled(clip.frame_time_secs).expect("resamples")
}

fn database(dir: &Path) -> (Vec<Clip>, Vec<Clip>) {
    let base: Vec<Clip> = CLIPS
        .iter()
        .map(|f| load_clip(&dir.join(f)).expect("loads"))
        .collect();
    let mut all = Vec::new();
    for speed in [0.85, 0.95, 1.05, 1.15] {
        all.extend(base.iter().map(|c| at_speed(c, speed)));
    }
    (base, all)
}

fn bench(c: &mut Criterion) {
    let Some(dir) = shared_data::shared_data_dir(CLIPS[0], "real clips") else {
        return;
    };
    let (base, db) = database(&dir);
    let frames: usize = db.iter().map(Clip::num_frames).sum();
    let s = GraphSettings::default();
    let g = MotionGraph::build(&db, s, &mut |_| {}).expect("builds");
    println!(
        "database: {frames} frames; kept {} ({:.1} %), {} transitions",
        g.num_kept(),
        100.0 * g.num_kept() as f64 / frames as f64,
        g.transitions.len()
    );
    let mut group = c.benchmark_group("graph");
    group.sample_size(10);
    group.bench_function("graph_build_10k_frames", |b| {
        b.iter(|| MotionGraph::build(black_box(&db), s, &mut |_| {}).expect("builds"))
    });

    let ft = base[0].frame_time_secs;
    let features = graph_features::clip_features(&base, &s);
    let p = SearchParams {
        stride: 1,
        radius: GraphSettings::frames(s.minimum_radius_secs, ft, 2),
        min_gap: GraphSettings::frames(s.window_secs, ft, 2),
        threshold: s.threshold,
    };
    group.bench_function("graph_search_exhaustive_2508_frames", |b| {
        b.iter(|| find_similar_exhaustive(black_box(&features), p))
    });
    group.finish();

    let rig = &db[1];
    let played = clips_onto_rig(&db, rig).expect("retargets");
    let analysis = analyze(&SkeletonView::from_clip(&rig.skeleton, &rig.poses));
    let pb = Playback::new(&g, &played, &analysis).expect("playback");
    let mut walker = Walker::new(&g, &pb, 3);
    let mut out = rig.skeleton.rest_pose();
    c.bench_function("graph_walk_step", |b| {
        b.iter(|| walker.step(&pb, black_box(&mut out)))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
