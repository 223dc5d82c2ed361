//! Per-frame costs of a live graft on the `rigcast bench` workload's 65-bone humanoid: the
//! waist splice (two FKs, the spine blend) and the looping stride (sample, seam-closed stride,
//! travel carried on); baseline in the same run: copying a 65-bone pose.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use glam::Vec3;
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{find_legs, PlantTrack};
use rigcast_retarget::graft::{BodySplit, GaitLoop, Splice};
use rigcast_retarget::retarget::workloads::humanoid_from_cmu;
use rigcast_retarget::Clip;

fn bench(c: &mut Criterion) {
    let w = humanoid_from_cmu().expect("corpus builds");
    let mut mapping = w.mapping().expect("workload builds");
    let outs = w.retargeted(&mut mapping).expect("apply");
    let ta = analyze(&SkeletonView::rest(&w.target));
    let split = BodySplit::new(&w.target, &ta, 3).expect("the humanoid splits");
    let mut splice = Splice::new(&w.target, split);
    let mut out = mapping.new_target_pose();
    let n = outs.len();
    let mut k = 0;
    c.bench_function("graft_splice_humanoid65", |b| {
        b.iter(|| {
            k = (k + 1) % n;
            splice.apply(
                black_box(&outs[k]),
                black_box(&outs[(k + 37) % n]),
                &mut out,
            )
        })
    });
    // A stride from frame 10 to 70 (landings every 30 frames, alternating feet).
    let legs = find_legs(&w.target, &ta);
    let flags = (0..n)
        .flat_map(|f| (0..legs.len()).map(move |l| f >= 10 + 30 * l && (f - 10 - 30 * l) % 60 < 20))
        .collect();
    let plants = PlantTrack::from_flags(legs, flags);
    let clip = Clip::new("walk", w.target.clone().into(), outs.clone(), 1.0 / 60.0).expect("clip");
    let mut gait = GaitLoop::new(&clip, &plants, Vec3::Y).expect("a stride");
    c.bench_function("graft_gait_loop_advance_humanoid65", |b| {
        b.iter(|| black_box(gait.advance(black_box(1.0 / 60.0), &mut out).len()))
    });
    c.bench_function("copy_pose_humanoid65_baseline", |b| {
        b.iter(|| {
            k = (k + 1) % n;
            out.copy_from(black_box(&outs[k]));
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
