//! The analysis recovers the corpus' ground-truth roles.
#![allow(clippy::unwrap_used)] // tests may unwrap

use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::corpus;

mod common;
use common::is_core;

#[test]
fn core_roles_match_ground_truth() {
    let mut failures = Vec::new();
    let extra = [
        corpus::creature_187().unwrap(),
        corpus::humanoid_65().unwrap(),
    ];
    for e in corpus::all().into_iter().chain(extra) {
        let a = analyze(&SkeletonView::rest(&e.skeleton));
        let mut wrong = Vec::new();
        let mut total = 0;
        for b in e.skeleton.bone_ids() {
            let truth = &e.labels[b.index()];
            if !is_core(truth) {
                continue;
            }
            total += 1;
            let got = a.label(b);
            if &got != truth {
                wrong.push(format!("{}: {} != {}", e.skeleton.name(b), got, truth));
            }
        }
        println!(
            "{:24} {:2}/{:2} core roles  up={:?} fwd={:?}",
            e.name,
            total - wrong.len(),
            total,
            a.up,
            a.forward
        );
        for w in &wrong {
            println!("    {w}");
        }
        if !wrong.is_empty() {
            failures.push(e.name.clone());
        }
    }
    assert!(failures.is_empty(), "core roles wrong in {failures:?}");
}

/// The skull-top leaf of a demo-like head chain (`neck` → `head` → `head_top`, no `_end` in
/// the name, no end joints on the toes) is the head's end marker, not the head; with names and
/// without (anonymous ids, shuffled children), in T- and A-pose.
#[test]
fn skull_top_leaf_is_head_end_not_head() {
    let entries: Vec<_> = ["head_top", "head_top_apose", "head_top_anon"]
        .iter()
        .map(|n| corpus::get(n).unwrap_or_else(|| panic!("corpus entry {n}")))
        .collect();
    for e in entries {
        let a = analyze(&SkeletonView::rest(&e.skeleton));
        for want in ["neck", "head", "head_end"] {
            let b = e
                .skeleton
                .bone_ids()
                .find(|b| e.labels[b.index()] == want)
                .unwrap();
            assert_eq!(a.label(b), want, "{}: {}", e.name, e.skeleton.name(b));
        }
    }
}
