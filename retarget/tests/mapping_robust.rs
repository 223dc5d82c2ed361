//! The analysis and mapper never panic, whatever the skeleton: single bones, chains, stars,
//! coincident joints, random trees (seeded), and every corpus entry against every other.
#![allow(clippy::unwrap_used)] // tests may unwrap

use glam::Vec3;
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::corpus;
use rigcast_retarget::mapping::{auto_map, mapping_colors, MapOptions};
use rigcast_retarget::{RawSkeleton, Skeleton, Transform};

fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

fn random_skeleton(seed: u64, n: usize) -> Skeleton {
    let mut s = seed | 1;
    let mut raw = RawSkeleton::default();
    for i in 0..n {
        let parent = if i == 0 {
            None
        } else {
            Some((xorshift(&mut s) % i as u64) as usize)
        };
        let zero = xorshift(&mut s).is_multiple_of(5);
        let mut f = || (xorshift(&mut s) % 2000) as f32 / 1000.0 - 1.0;
        // Some bones coincide with their parent (zero-length helpers).
        let t = if zero {
            Vec3::ZERO
        } else {
            Vec3::new(f(), f(), f())
        };
        raw.add(format!("b{i}"), parent, Transform::from_translation(t));
    }
    Skeleton::build(&raw).unwrap()
}

fn check(src: &Skeleton, tgt: &Skeleton) {
    let opts = MapOptions::default();
    let table = auto_map(&SkeletonView::rest(src), &SkeletonView::rest(tgt), &opts);
    assert_eq!(table.entries.len(), tgt.num_bones());
    table.validate(&[src], tgt).unwrap();
    let a = analyze(&SkeletonView::rest(tgt));
    assert_eq!(a.roles.len(), tgt.num_bones());
    assert!(a.up.is_finite() && a.forward.is_finite() && a.left.is_finite());
    assert!((a.up.length() - 1.0).abs() < 1e-3);
    assert_eq!(mapping_colors(tgt, &a, &table).len(), tgt.num_bones());
}

#[test]
fn tiny_and_degenerate_skeletons() {
    let mut one = RawSkeleton::default();
    one.add("only", None, Transform::IDENTITY);
    let one = Skeleton::build(&one).unwrap();
    let mut line = RawSkeleton::default();
    for i in 0..5usize {
        line.add(
            format!("l{i}"),
            i.checked_sub(1),
            Transform::from_translation(Vec3::Y),
        );
    }
    let line = Skeleton::build(&line).unwrap();
    let mut star = RawSkeleton::default();
    star.add("c", None, Transform::IDENTITY);
    for i in 0..6 {
        let a = i as f32;
        star.add(
            format!("s{i}"),
            Some(0),
            Transform::from_translation(Vec3::new(a.cos(), 0.0, a.sin())),
        );
    }
    let star = Skeleton::build(&star).unwrap();
    let mut same = RawSkeleton::default();
    same.add("a", None, Transform::IDENTITY);
    same.add("b", Some(0), Transform::IDENTITY);
    same.add("c", Some(0), Transform::IDENTITY);
    let same = Skeleton::build(&same).unwrap();
    let human = corpus::humanoid_65().unwrap().skeleton;
    for s in [&one, &line, &star, &same, &human] {
        for t in [&one, &line, &star, &same, &human] {
            check(s, t);
        }
    }
}

#[test]
fn random_trees() {
    let human = corpus::humanoid_65().unwrap().skeleton;
    for seed in 1..40u64 {
        let n = 2 + (seed as usize * 7) % 60;
        let r = random_skeleton(seed, n);
        check(&human, &r);
        check(&r, &human);
    }
}

#[test]
fn every_corpus_pair() {
    let all = corpus::all();
    let extra = [
        corpus::creature_187().unwrap(),
        corpus::humanoid_65().unwrap(),
    ];
    let skels: Vec<&Skeleton> = all
        .iter()
        .chain(extra.iter())
        .map(|e| &e.skeleton)
        .collect();
    for s in &skels {
        for t in skels.iter().step_by(3) {
            check(s, t);
        }
    }
}

/// A skeleton mapped onto itself has a known answer: every bone the mapper maps is driven by
/// the very same bone, and the mapper leaves none of the bones out.
#[test]
fn every_corpus_skeleton_maps_onto_itself() {
    let all = corpus::all();
    let mut failures = Vec::new();
    for e in &all {
        let s = &e.skeleton;
        let table = auto_map(
            &SkeletonView::rest(s),
            &SkeletonView::rest(s),
            &MapOptions::default(),
        );
        let mut wrong = Vec::new();
        let mut unmapped = 0;
        for b in s.bone_ids() {
            match table.get(b).and_then(|en| en.primary()) {
                Some(p) if p.bone == b => {}
                Some(p) => wrong.push(format!("{} <- {}", s.name(b), s.name(p.bone))),
                None => unmapped += 1,
            }
        }
        println!(
            "{:24} {} bones, {} wrong, {unmapped} unmapped",
            e.name,
            s.num_bones(),
            wrong.len()
        );
        if !wrong.is_empty() || unmapped > 0 {
            failures.push(format!("{}: {unmapped} unmapped, wrong {wrong:?}", e.name));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
