//! Graft build time on real data (the acceptance pair: PyMO's Meredith walk's upper body on
//! CMU 131_01, 994 frames at 120 fps), end to end as `rigcast graft` runs it (analyses,
//! mapping, retargeting the upper clip, plants on both rigs, clustering, pairing, warp,
//! synthesis), and the planning and synthesis alone; baseline in the same run: a plain offline
//! retarget of the upper clip onto the walk's rig (`rigcast retarget`'s work without the lock).
//! The pair is named: BENCHMARKS.md's grafting figures are measured on it, and the graft's own
//! judge holds for it alone today (`server/tests/graft_real.rs`: the same judge with the other
//! labelled walks' upper bodies is ignored with its figures). Prints a note and measures
//! nothing when either file is absent.
use criterion::{criterion_group, criterion_main, Criterion};
use rigcast_retarget::graft::{self, BodySplit, GraftSettings};
use rigcast_retarget::RootMotion;
use rigcast_server::offline::{graft_clips, plants};
use rigcast_server::offline::{plan_mapping, retarget_clip};

#[path = "../../sources/tests/common/shared_data.rs"]
mod shared_data;

fn bench(c: &mut Criterion) {
    let files = [
        "zoo/bvh/sparse_spine_head__pymo_meredith.bvh",
        "bvh/cmu_131_01_walk.bvh",
    ];
    let Some([up, low]) = shared_data::shared_data_all(files) else {
        return;
    };
    let upper = rigcast_sources::load_clip(&up).expect("upper loads");
    let lower = rigcast_sources::load_clip(&low).expect("lower loads");
    let settings = GraftSettings::default();
    let mut group = c.benchmark_group("graft_meredith_on_cmu131_994_frames");
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
    group.bench_function("synthesize_994_frames", |b| {
        b.iter(|| {
            graft::synthesize(&g.plan, &g.upper_on_lower, &lower, &split, &mut |_, _| {})
                .expect("synthesize")
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
