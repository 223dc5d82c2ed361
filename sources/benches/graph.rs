//! Motion graphs on real capture (`../shared/data`; skipped with a message when absent). The
//! clips are the labelled human captures the tests' graphs take (a second or more of motion
//! each, at 120 Hz, the first in sorted order within 2,600 frames: the size of the recorded
//! figures' workload, 2,508 frames in four clips on today's data); the frames are printed.
//!
//! - `graph_build_10k_frames`: the whole build (analysis, features, pruned search, SCC) of a
//!   database of the clips each at four playback speeds (0.85×, 0.95×, 1.05×, 1.15×,
//!   resampled back to 120 Hz), about 10,000 frames — like several takes of the same moves;
//! - `graph_search_exhaustive_2508_frames` (the baseline): the naive all-pairs search at full
//!   resolution over the clips at 1× (the 4× database would take 16× as long: O(N²));
//! - `graph_walk_step`: one frame of a wandering walker on the 4× graph, played on the second
//!   clip's rig (the live fallback's per-tick cost).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::graph::play::clips_onto_rig;
use rigcast_retarget::graph::search::{find_similar_exhaustive, SearchParams};
use rigcast_retarget::graph::{GraphSettings, MotionGraph, Playback, Walker};
use rigcast_retarget::Clip;

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

fn database(base: Vec<Clip>) -> (Vec<Clip>, Vec<Clip>) {
    let mut all = Vec::new();
    for speed in [0.85, 0.95, 1.05, 1.15] {
        all.extend(base.iter().map(|c| at_speed(c, speed)));
    }
    (base, all)
}

fn bench(c: &mut Criterion) {
    let base: Vec<Clip> = shared_data::graph_clips(2600)
        .into_iter()
        .map(|(_, clip)| clip)
        .collect();
    if base.len() < 2 {
        println!("SKIP: fewer than two labelled human clips for a graph");
        return;
    }
    let (base, db) = database(base);
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
