//! Issue 3 acceptance over the generated corpus: every humanoid pair, anonymous targets,
//! quadruped targets, seed 000's six-bone arm.
#![allow(clippy::unwrap_used)] // tests may unwrap

use rigcast_retarget::analysis::SkeletonView;
use rigcast_retarget::corpus::{self, CorpusEntry, Kind, Variant};
use rigcast_retarget::mapping::{auto_map, MapOptions, MappingTable};

mod common;
use common::{is_core, strip_side};

/// (correct, total) over target core bones whose label exists in the source; plus the list
/// of left/right swaps anywhere in the table.
fn score(
    src: &CorpusEntry,
    tgt: &CorpusEntry,
    table: &MappingTable,
) -> (usize, usize, Vec<String>, Vec<String>) {
    let mut ok = 0;
    let mut total = 0;
    let mut wrong = Vec::new();
    let mut swaps = Vec::new();
    for t in tgt.skeleton.bone_ids() {
        let truth = &tgt.labels[t.index()];
        let mapped = table.get(t).and_then(|e| e.primary()).map(|p| p.bone);
        if let Some(s) = mapped {
            let (_, ts) = strip_side(truth);
            let (_, ss) = strip_side(&src.labels[s.index()]);
            if ts.is_some() && ss.is_some() && ts != ss {
                swaps.push(format!(
                    "{} <- {}",
                    tgt.skeleton.name(t),
                    src.skeleton.name(s)
                ));
            }
        }
        if !is_core(truth) || !src.labels.contains(truth) {
            continue;
        }
        total += 1;
        match mapped {
            Some(s) if &src.labels[s.index()] == truth => ok += 1,
            other => wrong.push(format!(
                "{} ({truth}) <- {}",
                tgt.skeleton.name(t),
                other
                    .map(|s| format!("{} ({})", src.skeleton.name(s), src.labels[s.index()]))
                    .unwrap_or("none".into())
            )),
        }
    }
    (ok, total, wrong, swaps)
}

fn humanoid_like(e: &CorpusEntry) -> bool {
    matches!(
        e.kind,
        Kind::Humanoid | Kind::Winged | Kind::FourArmed | Kind::Tailed
    )
}

fn run_pairs(target_variant: Variant, min_ratio: f64) {
    let all = corpus::all();
    let opts = MapOptions::default();
    let mut worst = 1.0f64;
    let mut failures = Vec::new();
    let (mut ok_all, mut total_all) = (0, 0);
    for src in all
        .iter()
        .filter(|e| humanoid_like(e) && e.variant != Variant::Anonymous)
    {
        for tgt in all
            .iter()
            .filter(|e| humanoid_like(e) && e.variant == target_variant)
        {
            let table = auto_map(
                &SkeletonView::rest(&src.skeleton),
                &SkeletonView::rest(&tgt.skeleton),
                &opts,
            );
            let (ok, total, wrong, swaps) = score(src, tgt, &table);
            ok_all += ok;
            total_all += total;
            let ratio = ok as f64 / total.max(1) as f64;
            worst = worst.min(ratio);
            if ratio < min_ratio || !swaps.is_empty() {
                failures.push(format!(
                    "{} -> {}: {ok}/{total} wrong {wrong:?} swaps {swaps:?}",
                    src.name, tgt.name
                ));
            }
        }
    }
    println!("core roles correct: {ok_all}/{total_all}, worst pair {worst:.3}");
    assert!(
        failures.is_empty(),
        "{} failing pairs:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn every_humanoid_pair_maps_core_roles_with_names() {
    run_pairs(Variant::TPose, 0.98);
    run_pairs(Variant::APose, 0.98);
}

#[test]
fn meaningless_target_names_still_map() {
    run_pairs(Variant::Anonymous, 0.95);
}

#[test]
fn quadruped_targets_take_legs_from_legs_and_front_legs_from_arms() {
    let all = corpus::all();
    let opts = MapOptions::default();
    let dragon = corpus::creature_187().unwrap();
    for tgt in all
        .iter()
        .filter(|e| e.kind == Kind::Quadruped)
        .chain(std::iter::once(&dragon))
    {
        for src in all.iter().filter(|e| e.kind == Kind::Humanoid) {
            let table = auto_map(
                &SkeletonView::rest(&src.skeleton),
                &SkeletonView::rest(&tgt.skeleton),
                &opts,
            );
            let (_, _, _, swaps) = score(src, tgt, &table);
            assert!(
                swaps.is_empty(),
                "{} -> {}: swaps {swaps:?}",
                src.name,
                tgt.name
            );
            for side in ["left", "right"] {
                for (t_role, s_role) in [
                    ("upper_leg", "upper_leg"),
                    ("lower_leg", "lower_leg"),
                    ("upper_arm", "upper_arm"),
                    ("lower_arm", "lower_arm"),
                ] {
                    let tl = format!("{side}_{t_role}");
                    let sl = format!("{side}_{s_role}");
                    let t = tgt
                        .labels
                        .iter()
                        .position(|l| *l == tl)
                        .expect("target bone");
                    let e = table.entries[t]
                        .as_ref()
                        .unwrap_or_else(|| panic!("{} -> {}: {tl} unmapped", src.name, tgt.name));
                    let s = e.primary().unwrap().bone;
                    assert_eq!(
                        src.labels[s.index()],
                        sl,
                        "{} -> {}: {tl}",
                        src.name,
                        tgt.name
                    );
                }
            }
        }
    }
}

#[test]
fn six_bone_arm_maps_wrist_to_wrist() {
    let (six, four) = corpus::seed000_arms().unwrap();
    // Both directions: 6 → 4 and 4 → 6.
    for (src, tgt) in [(&six, &four), (&four, &six)] {
        let table = auto_map(
            &SkeletonView::rest(&src.skeleton),
            &SkeletonView::rest(&tgt.skeleton),
            &MapOptions::default(),
        );
        for side in ["left", "right"] {
            for role in ["clavicle", "upper_arm", "lower_arm", "hand"] {
                let l = format!("{side}_{role}");
                let t = tgt.labels.iter().position(|x| *x == l).unwrap();
                let s = table.entries[t]
                    .as_ref()
                    .and_then(|e| e.primary())
                    .map(|p| p.bone);
                let got = s.map(|s| src.labels[s.index()].clone());
                assert_eq!(
                    got.as_deref(),
                    Some(l.as_str()),
                    "{} -> {}",
                    src.name,
                    tgt.name
                );
            }
        }
        // The fingertip never drives the wrist.
        let tip = src.skeleton.bone("left_hand_tip");
        if let Some(tip) = tip {
            assert!(table
                .entries
                .iter()
                .flatten()
                .all(|e| e.primary().unwrap().bone != tip || e.score < 0.0));
        }
    }
}

/// Issue 3 regression: a head chain ending in a skull-top leaf whose name does not say "end"
/// (rigcast's demo layout), as source or target, named or anonymous, maps head → head and
/// neck → neck with every humanoid, including UE-style targets whose head is a leaf.
#[test]
fn skull_top_leaf_never_drives_the_head() {
    let all = corpus::all();
    let opts = MapOptions::default();
    let mut failures = Vec::new();
    let mut checked = 0;
    for src in all.iter().filter(|e| e.kind == Kind::Humanoid) {
        for tgt in all.iter().filter(|e| e.kind == Kind::Humanoid) {
            if !src.name.starts_with("head_top") && !tgt.name.starts_with("head_top") {
                continue;
            }
            let table = auto_map(
                &SkeletonView::rest(&src.skeleton),
                &SkeletonView::rest(&tgt.skeleton),
                &opts,
            );
            for role in ["neck", "head"] {
                let Some(t) = tgt.labels.iter().position(|l| l == role) else {
                    continue;
                };
                if !src.labels.iter().any(|l| l == role) {
                    continue;
                }
                checked += 1;
                let got = table.entries[t]
                    .as_ref()
                    .and_then(|e| e.primary())
                    .map(|p| src.labels[p.bone.index()].as_str());
                if got != Some(role) {
                    failures.push(format!("{} -> {}: {role} <- {got:?}", src.name, tgt.name));
                }
            }
        }
    }
    // 10 humanoids × 3 variants; the UE mannequin (head a leaf) is among the targets.
    assert!(checked > 100, "only {checked} checks");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
