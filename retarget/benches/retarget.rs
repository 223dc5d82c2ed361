//! Retargeting benchmarks on the fixed workloads of `rigcast_retarget::retarget::workloads`
//! (the same ones `rigcast bench` runs): per-frame apply for the corpus's 65-bone humanoid ←
//! 31-bone CMU skeleton and 187-bone creature ← humanoid, FK of the 65-bone humanoid, and
//! `Mapping::build` (the automatic mapping itself is benchmarked in `benches/mapping.rs`).
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use rigcast_retarget::retarget::workloads::{creature_from_humanoid, humanoid_from_cmu, Workload};
use rigcast_retarget::{forward_kinematics, Mapping, RetargetOptions, WorldTransform};

fn per_frame(c: &mut Criterion, name: &str, w: &Workload) {
    let mut mapping = w.mapping().expect("workload builds");
    let mut out = mapping.new_target_pose();
    let mut i = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            i = (i + 1) % w.poses.len();
            mapping
                .apply_one(black_box(&w.poses[i]), &mut out)
                .expect("apply");
        })
    });
}

fn bench(c: &mut Criterion) {
    let humanoid = humanoid_from_cmu().expect("corpus builds");
    let creature = creature_from_humanoid().expect("corpus builds");
    per_frame(c, "retarget_humanoid65_from_cmu31", &humanoid);
    per_frame(c, "retarget_creature187_from_humanoid65", &creature);

    let target = &humanoid.target;
    let pose = target.rest_pose();
    let mut worlds = vec![WorldTransform::IDENTITY; target.num_bones()];
    c.bench_function("fk_humanoid65", |b| {
        b.iter(|| forward_kinematics(black_box(target), black_box(&pose), &mut worlds))
    });

    c.bench_function("mapping_build_humanoid65_from_cmu31", |b| {
        b.iter(|| {
            Mapping::build(
                &[black_box(&humanoid.source)],
                &humanoid.target,
                &humanoid.table,
                &RetargetOptions::default(),
            )
            .expect("build")
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
