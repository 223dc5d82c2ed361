//! Graft build time on real data (the second labelled walk's upper body on the first, both
//! found by their motion; on today's data CMU's 31-joint walk on CMU 131_01, 994 frames at 120
//! fps; the pair is printed), end to end as `rigcast graft` runs it (analyses,
//! mapping, retargeting the upper clip, plants on both rigs, clustering, pairing, warp,
//! synthesis), and the planning and synthesis alone; baseline in the same run: a plain offline
//! retarget of the upper clip onto the walk's rig (`rigcast retarget`'s work without the lock).
//! Prints a note and measures nothing when the shared data is absent.
use criterion::{criterion_group, criterion_main, Criterion};
use rigcast_retarget::graft::{self, BodySplit, GraftSettings};
use rigcast_retarget::RootMotion;
use rigcast_server::offline::{graft_clips, plants};
use rigcast_server::offline::{plan_mapping, retarget_clip};

#[path = "../../sources/tests/common/shared_data.rs"]
#[allow(dead_code)]
mod shared_data;

fn bench(c: &mut Criterion) {
    let mut walks = shared_data::first_walks(2).into_iter();
    let (Some((low, lower, _)), Some((up, upper, _))) = (walks.next(), walks.next()) else {
        eprintln!("fewer than two labelled walks: nothing measured");
        return;
    };
    println!(
        "{}'s upper body on {} ({} frames)",
        up.rel,
        low.rel,
        lower.num_frames()
    );
    let settings = GraftSettings::default();
    let mut group = c.benchmark_group("graft_upper_on_a_walk");
    group.sample_size(10);
    group.bench_function("graft_build_end_to_end", |b| {
        b.iter(|| graft_clips(&upper, &lower, None, &settings, &mut |_, _| {}).expect("graft"))
    });
    let plan = plan_mapping(&upper, &lower, None).expect("plan");
    let opts = plan.retarget_options(&upper, RootMotion::InPlace);
    group.bench_function("baseline_plain_retarget_of_the_upper_clip", |b| {
        b.iter(|| {
            retarget_clip(&upper, &lower.skeleton, &plan.table, &opts, &mut |_| {})
                .expect("retarget")
        })
    });
    let g = graft_clips(&upper, &lower, None, &settings, &mut |_, _| {}).expect("graft");
    let split = BodySplit::new(&lower.skeleton, &plan.target_analysis, settings.blend_bones)
        .expect("split");
    let (pu, pl) = (
        plants(&upper, &plan.source_analysis),
        plants(&lower, &plan.target_analysis),
    );
    group.bench_function("plan_features_clusters_pairing_warp", |b| {
        b.iter(|| {
            graft::plan((&g.upper_on_lower, &pu), (&lower, &pl), &split, &settings).expect("plan")
        })
    });
    group.bench_function("synthesize_the_walk", |b| {
        b.iter(|| {
            graft::synthesize(&g.plan, &g.upper_on_lower, &lower, &split, &mut |_, _| {})
                .expect("synthesize")
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
