//! A VRM file's humanoid extension is ground truth for the mapper (issue 3, item 3).
//!
//! The target is the corpus VRoid-style humanoid with meaningless bone names and a misleading
//! geometry: its feet and toes point backwards (as on a rig modelled facing -Z with the feet
//! copied from a +Z rig). Inference reads the facing from the feet, so without the truth the
//! character's left and right come out swapped; the truth list (what a VRM's humanoid extension
//! holds) restores every core role.
#![allow(clippy::unwrap_used)] // tests may unwrap

use rigcast_retarget::analysis::truth::human_bone_role;
use rigcast_retarget::analysis::{analyze, analyze_with_truth, HumanBone, Side, SkeletonView};
use rigcast_retarget::corpus;
use rigcast_retarget::mapping::{map_analyzed, MapOptions, MappingTable};
use rigcast_retarget::{BoneId, Skeleton};

mod common;
use common::is_core;

/// Corpus label of a humanoid bone (the labels [`rigcast_retarget::analysis::BoneRole::label`]
/// writes), with the VRoid fixture's three spine bones above the hips.
fn label_of(h: HumanBone) -> String {
    let (role, side) = human_bone_role(h, true);
    let prefix = match side {
        Side::Left => "left_",
        Side::Right => "right_",
        Side::Center => "",
    };
    format!("{prefix}{}", role.name())
}

/// The truth list a VRM exporter would write: every humanoid bone the skeleton has.
fn truth_for(skel: &Skeleton, labels: &[String]) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for h in HumanBone::ALL {
        let l = label_of(*h);
        if let Some(b) = skel.bone_ids().find(|b| labels[b.index()] == l) {
            out.push((h.vrm_name().to_string(), skel.name(b).to_string()));
        }
    }
    out
}

/// Anonymous VRoid humanoid whose feet point backwards: every bone below a foot is mirrored
/// front-to-back about the ankle.
fn backward_feet() -> (Skeleton, Vec<String>) {
    let e = corpus::get("vrm_anon").unwrap();
    let skel = &e.skeleton;
    let mut raw = skel.to_raw();
    let below_foot = |b: BoneId| {
        let mut p = skel.parent(b);
        while let Some(x) = p {
            if e.labels[x.index()].ends_with("_foot") {
                return true;
            }
            p = skel.parent(x);
        }
        false
    };
    for b in skel.bone_ids() {
        if below_foot(b) {
            let t = &mut raw.bones[b.index()].rest.translation;
            t.z = -t.z;
        }
    }
    (Skeleton::build(&raw).unwrap(), e.labels.clone())
}

/// Correct core-role mappings out of the core-role target bones, and the wrong ones' labels.
fn score_core(
    table: &MappingTable,
    src_labels: &[String],
    tgt: &Skeleton,
    tgt_labels: &[String],
) -> (usize, usize, Vec<String>) {
    let (mut ok, mut n, mut wrong) = (0, 0, Vec::new());
    for t in tgt.bone_ids() {
        let want = &tgt_labels[t.index()];
        if !is_core(want) {
            continue;
        }
        n += 1;
        let got = table
            .get(t)
            .and_then(|e| e.primary())
            .map(|p| src_labels[p.bone.index()].clone());
        if got.as_deref() == Some(want.as_str()) {
            ok += 1;
        } else {
            wrong.push(format!("{want}<-{got:?}"));
        }
    }
    (ok, n, wrong)
}

#[test]
fn vrm_truth_fixes_backward_feet() {
    let src = corpus::get("mixamo").unwrap();
    let (tgt, labels) = backward_feet();
    let truth = truth_for(&tgt, &labels);
    assert!(truth.len() >= 50, "truth has {} bones", truth.len());
    let sa = analyze(&SkeletonView::rest(&src.skeleton));
    let opts = MapOptions::default();

    let ta_plain = analyze(&SkeletonView::rest(&tgt));
    let plain = map_analyzed(&[(&src.skeleton, &sa)], (&tgt, &ta_plain), &opts);
    let (ok_p, n, wrong_p) = score_core(&plain, &src.labels, &tgt, &labels);
    println!("without truth: {ok_p}/{n} {wrong_p:?}");

    let ta = analyze_with_truth(&SkeletonView::rest(&tgt), Some(&truth));
    let with = map_analyzed(&[(&src.skeleton, &sa)], (&tgt, &ta), &opts);
    let (ok_t, n2, wrong_t) = score_core(&with, &src.labels, &tgt, &labels);
    println!("with truth: {ok_t}/{n2} {wrong_t:?}");
    assert_eq!(n, n2);
    assert_eq!(ok_t, n, "with the truth every core role maps: {wrong_t:?}");
    // The truth changed the outcome: inference alone swaps the sides of the sided core bones.
    assert!(
        ok_p + 8 <= n,
        "inference alone already got {ok_p}/{n} right"
    );
    let swapped = tgt
        .bone_ids()
        .filter(|b| labels[b.index()].starts_with("left_"))
        .filter(|b| ta_plain.roles[b.index()].side == Side::Right)
        .count();
    assert!(swapped >= 8, "only {swapped} left bones inferred as right");
    // With the truth every named bone carries its VRM role and side at full confidence, and the
    // facing (hence orientation evidence) was flipped with it.
    for (h, name) in &truth {
        let b = tgt.bone(name).unwrap();
        assert_eq!(ta.label(b), labels[b.index()], "{h}");
        assert_eq!(ta.roles[b.index()].confidence, 1.0);
    }
    assert!(ta.forward.dot(ta_plain.forward) < -0.99);
}

#[test]
fn no_truth_is_plain_analysis_and_unknown_names_are_ignored() {
    let e = corpus::get("vrm_anon").unwrap();
    let view = SkeletonView::rest(&e.skeleton);
    let plain = analyze(&view);
    assert_eq!(analyze_with_truth(&view, None), plain);
    let junk = vec![
        (
            "notABone".to_string(),
            e.skeleton.name(BoneId(0)).to_string(),
        ),
        ("hips".to_string(), "no such bone".to_string()),
    ];
    assert_eq!(analyze_with_truth(&view, Some(&junk)), plain);
}

#[test]
fn truth_takes_a_role_away_from_the_inferred_bone() {
    // Claim the inferred chest's parent is the chest: the old chest no longer is one.
    let e = corpus::get("mixamo").unwrap();
    let skel = &e.skeleton;
    let view = SkeletonView::rest(skel);
    let plain = analyze(&view);
    let chest = plain
        .find(rigcast_retarget::analysis::Role::Chest, Side::Center)
        .unwrap();
    let below = skel.parent(chest).unwrap();
    let truth = vec![("chest".to_string(), skel.name(below).to_string())];
    let a = analyze_with_truth(&view, Some(&truth));
    assert_eq!(a.label(below), "chest");
    assert_ne!(a.label(chest), "chest");
    assert_eq!(
        a.find(rigcast_retarget::analysis::Role::Chest, Side::Center),
        Some(below)
    );
}
