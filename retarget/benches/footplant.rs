//! Footplant detection and foot locking per frame, on the `rigcast bench` workload (65-bone
//! corpus humanoid driven by the 31-bone CMU skeleton's walk): causal detection on the source,
//! two-sided detection over the clip (per frame), the lock + IK with both feet held (its
//! costliest path), and the whole live step (detection + lock).
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{
    detect_clip, find_legs, FootLock, LockSettings, PlantDetector, PlantSettings,
};
use rigcast_retarget::retarget::workloads::humanoid_from_cmu;

fn bench(c: &mut Criterion) {
    let w = humanoid_from_cmu().expect("corpus builds");
    let sa = analyze(&SkeletonView::from_clip(&w.source, &w.poses));
    let ta = analyze(&SkeletonView::rest(&w.target));
    let legs = find_legs(&w.source, &sa);
    assert_eq!(legs.len(), 2);
    let dt = 1.0 / 60.0;

    let mut detector = PlantDetector::new(&w.source, &legs, sa.up, PlantSettings::default());
    let mut i = 0;
    c.bench_function("footplant_detect_causal_cmu31", |b| {
        b.iter(|| {
            i = (i + 1) % w.poses.len();
            black_box(detector.push(&w.source, black_box(&w.poses[i]), dt));
        })
    });
    c.bench_function("footplant_detect_two_sided_cmu31_x120_frames", |b| {
        b.iter(|| {
            detect_clip(
                &w.source,
                &legs,
                black_box(&w.poses),
                dt,
                sa.up,
                &PlantSettings::default(),
            )
        })
    });

    let mut mapping = w.mapping().expect("workload builds");
    let mut lock = FootLock::new(&mapping, &sa, &ta, LockSettings::default()).expect("legs");
    let outs = w.retargeted(&mut mapping).expect("apply");
    let mut out = mapping.new_target_pose();
    let mut k = 0;
    c.bench_function("foot_lock_ik_humanoid65_both_planted", |b| {
        b.iter(|| {
            k = (k + 1) % outs.len();
            out.copy_from(&outs[k]);
            lock.apply_planted(black_box(&[true, true]), dt, &mut out);
        })
    });
    let mut k = 0;
    c.bench_function("foot_lock_live_humanoid65_from_cmu31", |b| {
        b.iter(|| {
            k = (k + 1) % outs.len();
            out.copy_from(&outs[k]);
            lock.apply_live(black_box(&w.poses[k]), true, dt, &mut out);
        })
    });
    c.bench_function("copy_pose_humanoid65_baseline", |b| {
        b.iter(|| {
            k = (k + 1) % outs.len();
            out.copy_from(black_box(&outs[k]));
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
