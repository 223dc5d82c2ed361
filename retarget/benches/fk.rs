//! FK of a 65-bone humanoid-sized skeleton.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use glam::{Quat, Vec3};
use rigcast_retarget::{forward_kinematics, RawSkeleton, Skeleton, Transform, WorldTransform};

fn skeleton_65() -> Skeleton {
    // A spine of 5, then 60 bones in 6 branches of 10 (arms/legs/fingers-like chains).
    let mut raw = RawSkeleton::default();
    let mut prev = raw.add("b0", None, Transform::IDENTITY);
    for i in 1..5 {
        prev = raw.add(
            format!("b{i}"),
            Some(prev),
            Transform::from_translation(Vec3::Y * 0.1),
        );
    }
    let spine_top = prev;
    let mut k = 5;
    for branch in 0..6 {
        let mut p = spine_top;
        for _ in 0..10 {
            let dir = Quat::from_rotation_y(branch as f32) * Vec3::X * 0.05;
            p = raw.add(
                format!("b{k}"),
                Some(p),
                Transform {
                    translation: dir,
                    rotation: Quat::from_rotation_z(0.1),
                },
            );
            k += 1;
        }
    }
    Skeleton::build(&raw).expect("valid skeleton")
}

fn bench(c: &mut Criterion) {
    let s = skeleton_65();
    assert_eq!(s.num_bones(), 65);
    let mut pose = s.rest_pose();
    for (i, r) in pose.rotations.iter_mut().enumerate() {
        *r = Quat::from_euler(glam::EulerRot::ZXY, i as f32 * 0.01, 0.2, -0.1);
    }
    let mut out = vec![WorldTransform::IDENTITY; s.num_bones()];
    c.bench_function("fk_65_bones", |b| {
        b.iter(|| forward_kinematics(black_box(&s), black_box(&pose), &mut out))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
