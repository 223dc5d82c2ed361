//! Automatic mapping speed: 187-bone creature ↔ 65-bone humanoid both ways (target < 10 ms
//! each; seed 004 took 3.1 s for its dragon) and a cached lookup (target < 100 µs).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use rigcast_retarget::analysis::SkeletonView;
use rigcast_retarget::corpus;
use rigcast_retarget::mapping::{auto_map, CacheKey, MapOptions, MappingCache};

fn bench(c: &mut Criterion) {
    let (Some(creature), Some(human)) = (corpus::creature_187(), corpus::humanoid_65()) else {
        return;
    };
    let cs = &creature.skeleton;
    let hs = &human.skeleton;
    println!(
        "creature bones: {}, humanoid bones: {}",
        cs.num_bones(),
        hs.num_bones()
    );
    let opts = MapOptions::default();
    for (name, from, to) in [
        ("map creature187 -> humanoid65", cs, hs),
        ("map humanoid65 -> creature187", hs, cs),
    ] {
        c.bench_function(name, |b| {
            b.iter(|| {
                auto_map(
                    &SkeletonView::rest(black_box(from)),
                    &SkeletonView::rest(to),
                    &opts,
                )
            })
        });
    }
    let mut cache = MappingCache::new();
    let key = CacheKey::new(&[hs], cs, &opts);
    cache.insert(
        key,
        auto_map(&SkeletonView::rest(hs), &SkeletonView::rest(cs), &opts),
    );
    // The lookup a reconnecting source does: build the key (fingerprints are precomputed in
    // the skeletons, options hashed) and fetch.
    c.bench_function("cached lookup (key + get)", |b| {
        b.iter(|| {
            let key = CacheKey::new(&[black_box(hs)], cs, &opts);
            cache.get(&key)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
