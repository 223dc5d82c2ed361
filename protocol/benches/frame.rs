//! Encode/decode of a 65-bone binary pose frame (a full humanoid with fingers), and VMC
#![allow(clippy::unwrap_used)]
//! encoding of the same pose. Inputs are built in advance from a fixed formula (no RNG).
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use glam::{Quat, Vec3};
use rigcast_protocol::frame::{decode_frame_into, encode_frame, FrameHeader};
use rigcast_protocol::vmc::{VmcBone, VmcEncoder};

const NUM_BONES: usize = 65;

fn rotations() -> Vec<Quat> {
    (0..NUM_BONES)
        .map(|i| Quat::from_euler(glam::EulerRot::YXZ, i as f32 * 0.1, 0.2, -0.05 * i as f32))
        .collect()
}

fn bench(c: &mut Criterion) {
    let rots = rotations();
    let header = FrameHeader {
        subject: 1,
        seq: 1000,
        capture_nanos: 1_700_000_000_000_000_000,
        send_nanos: 1_700_000_000_001_000_000,
        ..FrameHeader::default()
    };
    let root = Vec3::new(0.1, 0.9, -0.3);
    let mut buf = Vec::new();
    encode_frame(&mut buf, &header, root, &rots);

    c.bench_function("frame_encode_65", |b| {
        let mut out = Vec::new();
        b.iter(|| encode_frame(&mut out, black_box(&header), root, black_box(&rots)))
    });
    c.bench_function("frame_decode_65", |b| {
        let mut out = Vec::new();
        b.iter(|| decode_frame_into(black_box(&buf), &mut out).map(|(h, _)| h.seq))
    });
    let names: Vec<String> = (0..NUM_BONES).map(|i| format!("Bone{i:02}")).collect();
    let translations = vec![Vec3::new(0.0, 0.1, 0.0); NUM_BONES];
    c.bench_function("vmc_encode_65", |b| {
        let mut enc = VmcEncoder::new();
        b.iter(|| {
            enc.encode(
                0.5,
                names
                    .iter()
                    .zip(&translations)
                    .zip(&rots)
                    .map(|((n, &t), &r)| VmcBone {
                        name: n,
                        translation: t,
                        rotation: r,
                    }),
            )
            .len()
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
