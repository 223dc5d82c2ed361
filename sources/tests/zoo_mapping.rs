//! Skeleton analysis and automatic mapping judged on real rigs: every labelled file in
//! `../shared/data` (ground truth in `labels.json` and every `*/labels.json`, provenance in
//! each folder's `SOURCES.md`), skipped
//! with a printed reason when the data is absent.
//!
//! Scoring (per ordered pair source → target, on the core roles): a target role counts when
//! both files label it; it is right when the target's labelled bone for it is driven by a
//! source bone the source's labels accept for the same role. A *swap* is a sided role driven by
//! the source's bone for the other side. A target bone that plays two labelled roles (a rig
//! with one spine bone is both spine and chest) is right when it is driven by either. Each pair
//! is scored twice: names intact, and the target's names replaced by meaningless ids with the
//! children of every bone shuffled (the source keeps its names).
#![allow(clippy::unwrap_used)] // tests may unwrap

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::mapping::{auto_map, MapOptions};
use rigcast_retarget::{BoneId, Clip, Pose, RawBone, RawSkeleton, Skeleton};
use rigcast_sources::load_clip;

#[path = "common/shared_data.rs"]
mod shared_data;
use shared_data::{all_labels, shared_data_dir};

/// The humanoid roles the acceptance counts (sided ones get `.L` / `.R` in the labels).
const CORE: &[&str] = &[
    "hips", "spine", "chest", "neck", "head", "shoulder", "upperArm", "lowerArm", "hand",
    "upperLeg", "lowerLeg", "foot", "toes",
];

/// Quadruped leg roles (hind legs use the humanoid leg names).
const QUAD_LEGS: &[&str] = &[
    "upperLeg",
    "lowerLeg",
    "foot",
    "frontShoulder",
    "frontUpper",
    "frontLower",
    "frontFoot",
];

fn data_dir() -> Option<PathBuf> {
    shared_data_dir("labels.json", "real rigs")
}

/// One labelled file: its clip and its role → acceptable bone names.
struct Rig {
    key: String,
    kind: String,
    clip: Clip,
    roles: BTreeMap<String, Vec<String>>,
}

/// [`load_rigs`] of the shared data, or `None` (with a printed reason) when it is absent.
fn real_rigs() -> Option<Vec<Rig>> {
    Some(load_rigs(&data_dir()?))
}

/// Every labelled file of every label file (`labels.json`, `*/labels.json`).
fn load_rigs(dir: &Path) -> Vec<Rig> {
    let labels = all_labels(dir);
    let mut out = Vec::new();
    for (key, v) in &labels {
        let clip = load_clip(&dir.join(key)).unwrap_or_else(|e| panic!("{key}: {e}"));
        let mut roles = BTreeMap::new();
        for (role, names) in v.as_object().unwrap() {
            if let Some(list) = names.as_array() {
                let list = list
                    .iter()
                    .map(|n| n.as_str().unwrap().to_string())
                    .collect();
                roles.insert(role.clone(), list);
            }
        }
        out.push(Rig {
            key: key.clone(),
            kind: v["kind"].as_str().unwrap().to_string(),
            clip,
            roles,
        });
    }
    out
}

/// `source -> target`, the rigs' short names, for failure messages.
fn pair(src: &Rig, tgt: &Rig) -> String {
    format!("{} -> {}", short(&src.key), short(&tgt.key))
}

fn short(key: &str) -> &str {
    let f = key.rsplit('/').next().unwrap_or(key);
    f.split("__").next().unwrap_or(f)
}

/// Sided role names: `foot` → [`foot.L`, `foot.R`], `hips` → [`hips`].
fn expand(roles: &[&str], labels: &BTreeMap<String, Vec<String>>) -> Vec<String> {
    let mut out = Vec::new();
    for r in roles {
        if labels.contains_key(*r) {
            out.push(r.to_string());
        }
        for s in [".L", ".R"] {
            let k = format!("{r}{s}");
            if labels.contains_key(&k) {
                out.push(k);
            }
        }
    }
    out
}

fn other_side(role: &str) -> Option<String> {
    role.strip_suffix(".L")
        .map(|r| format!("{r}.R"))
        .or_else(|| role.strip_suffix(".R").map(|r| format!("{r}.L")))
}

/// A deterministic permutation (xorshift-seeded Fisher–Yates).
fn permutation(n: usize, seed: u64) -> Vec<usize> {
    let mut s = seed | 1;
    let mut v: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        v.swap(i, (s % (i as u64 + 1)) as usize);
    }
    v
}

/// The clip with every bone renamed to a meaningless id and children shuffled; returns the
/// new clip and, per new bone, its original name.
fn anonymise(clip: &Clip, seed: u64) -> (Clip, Vec<String>) {
    let skel = &clip.skeleton;
    let n = skel.num_bones();
    let order = permutation(n, seed);
    let ids = permutation(n, seed ^ 0x9e37_79b9);
    let mut raw = RawSkeleton::default();
    let mut raw_of = vec![0usize; n];
    for (k, &old) in order.iter().enumerate() {
        raw_of[old] = k;
    }
    for &old in &order {
        let b = BoneId(old as u16);
        raw.bones.push(RawBone {
            name: format!("j{}", ids[old]),
            parent: skel.parent(b).map(|p| raw_of[p.index()]),
            rest: skel.rest()[old],
        });
    }
    let new = Skeleton::build(&raw).unwrap();
    let old_of: Vec<usize> = new
        .bone_ids()
        .map(|b| {
            let id: usize = new.name(b)[1..].parse().unwrap();
            ids.iter().position(|&x| x == id).unwrap()
        })
        .collect();
    let poses: Vec<Pose> = clip
        .poses
        .iter()
        .map(|p| Pose {
            rotations: old_of.iter().map(|&o| p.rotations[o]).collect(),
            translations: old_of.iter().map(|&o| p.translations[o]).collect(),
        })
        .collect();
    let names = old_of
        .iter()
        .map(|&o| skel.name(BoneId(o as u16)).to_string())
        .collect();
    let clip = Clip::new(
        clip.name.clone(),
        std::sync::Arc::new(new),
        poses,
        clip.frame_time_secs,
    )
    .unwrap();
    (clip, names)
}

fn view(clip: &Clip) -> SkeletonView<'_> {
    SkeletonView::from_clip(&clip.skeleton, &clip.poses)
}

/// The automatic mapping of `src` onto `tgt`, both with their motion.
fn map_rigs(src: &Rig, tgt: &Rig) -> rigcast_retarget::mapping::MappingTable {
    auto_map(&view(&src.clip), &view(&tgt.clip), &MapOptions::default())
}

/// Name of the source bone driving target bone `t`, if it is mapped.
fn driver<'a>(
    table: &rigcast_retarget::mapping::MappingTable,
    ss: &'a Skeleton,
    t: BoneId,
) -> Option<&'a str> {
    table.entries[t.index()]
        .as_ref()
        .map(|e| ss.name(e.sources[0].bone))
}

#[derive(Default, Clone, Copy)]
struct Score {
    right: usize,
    total: usize,
    swaps: usize,
}

impl Score {
    fn add(&mut self, o: Score) {
        self.right += o.right;
        self.total += o.total;
        self.swaps += o.swaps;
    }
    fn pct(&self) -> f64 {
        100.0 * self.right as f64 / self.total.max(1) as f64
    }
}

/// One judged core role: whether the mapping got it right, whether the mapper flagged the
/// target bone, and the confidence it gave it (0 when unmapped).
#[derive(Clone)]
struct Judged {
    right: bool,
    flagged: bool,
    confidence: f32,
    note: String,
}

/// What scoring pairs leaves behind: failure lines and every judged role.
#[derive(Default)]
struct Log {
    fails: Vec<String>,
    judged: Vec<Judged>,
}

/// How the mapper judged target bone `k` (an index into the mapped clip's bones).
fn judged(table: &rigcast_retarget::mapping::MappingTable, k: usize, right: bool) -> Judged {
    let b = BoneId(k as u16);
    Judged {
        right,
        flagged: table.flag(b).is_some(),
        confidence: table.get(b).map_or(0.0, |e| e.confidence),
        note: table.get(b).map_or(String::new(), |e| {
            format!("{:.0} {}", e.score, e.evidence.join(","))
        }) + &table
            .flag(b)
            .map_or(String::new(), |f| format!(" FLAG {}", f.reason)),
    }
}

/// Maps `src` onto `tgt` (optionally anonymised) and scores the `roles`.
fn score_pair(src: &Rig, tgt: &Rig, roles: &[&str], anon: bool, log: &mut Log) -> Score {
    let (tclip, tnames) = if anon {
        anonymise(&tgt.clip, 0x5eed ^ tgt.key.len() as u64)
    } else {
        let names = tgt.clip.skeleton.names().to_vec();
        (tgt.clip.clone(), names)
    };
    let table = auto_map(&view(&src.clip), &view(&tclip), &MapOptions::default());
    let ss = &src.clip.skeleton;
    // Original target name → its index in the mapped clip, and which source bone drives it.
    let index_of = |tname: &str| tnames.iter().position(|n| n == tname);
    let driver_of =
        |tname: &str| -> Option<&str> { driver(&table, ss, BoneId(index_of(tname)? as u16)) };
    let mut sc = Score::default();
    let troles = expand(roles, &tgt.roles);
    for role in &troles {
        let Some(accept) = src.roles.get(role) else {
            continue;
        };
        let tlist = &tgt.roles[role];
        // Source names accepted for this role, and for the other roles its target bones play
        // (a one-spine rig's bone is both spine and chest).
        let mut ok_names: Vec<&String> = accept.iter().collect();
        for (r, list) in &tgt.roles {
            if r != role && list.iter().any(|b| tlist.contains(b)) && !r.starts_with("tail") {
                if let Some(a) = src.roles.get(r) {
                    ok_names.extend(a.iter());
                }
            }
        }
        sc.total += 1;
        let drivers: Vec<Option<&str>> = tlist.iter().map(|t| driver_of(t)).collect();
        let right_at = drivers
            .iter()
            .position(|d| d.is_some_and(|d| ok_names.iter().any(|n| *n == d)));
        if let Some(k) = index_of(&tlist[right_at.unwrap_or(0)]) {
            log.judged.push(judged(&table, k, right_at.is_some()));
        }
        if right_at.is_some() {
            sc.right += 1;
            continue;
        }
        let d = drivers[0];
        let swapped = other_side(role)
            .and_then(|o| src.roles.get(&o))
            .is_some_and(|o| d.is_some_and(|d| o.iter().any(|n| n == d)));
        if swapped {
            sc.swaps += 1;
        }
        let how = log.judged.last().map_or(String::new(), |j| {
            format!(
                " (confidence {:.2}{})",
                j.confidence,
                if j.flagged { ", flagged" } else { "" }
            )
        });
        log.fails.push(format!(
            "{} -> {}{}: {role} ({}) <- {}{}{how}",
            short(&src.key),
            short(&tgt.key),
            if anon { " [anon]" } else { "" },
            tlist[0],
            d.unwrap_or("-"),
            if swapped { "  SWAP" } else { "" }
        ));
    }
    sc
}

fn humans(rigs: &[Rig]) -> Vec<&Rig> {
    rigs.iter()
        .filter(|r| r.kind == "human" && !r.key.contains("kinect2"))
        .collect()
}

/// Per-file analysis report: which labelled core bones the analysis gives the right role.
#[test]
fn analysis_roles_per_file() {
    let Some(rigs) = real_rigs() else { return };
    for rig in &rigs {
        let a = analyze(&view(&rig.clip));
        let skel = &rig.clip.skeleton;
        let mut line = String::new();
        for role in expand(CORE, &rig.roles) {
            let bone = &rig.roles[&role][0];
            let Some(b) = skel.bone(bone) else { continue };
            line.push_str(&format!(" {role}:{}={}", bone, a.label(b)));
        }
        println!(
            "{:<28} up={:?} fwd={:?} humanoid={}\n   {line}",
            short(&rig.key),
            a.up,
            a.forward,
            a.humanoid
        );
    }
}

fn print_table(title: &str, rows: &[(String, Score, Score)]) {
    println!(
        "\n{title}\n{:<28} {:>12} {:>14}",
        "target", "names", "meaningless"
    );
    for (name, a, b) in rows {
        println!(
            "{name:<28} {:>6.1}% ({:>2}) {:>7.1}% ({:>2})",
            a.pct(),
            a.swaps,
            b.pct(),
            b.swaps
        );
    }
}

/// Every ordered pair of labelled humans, both modes: the per-target rows (names intact,
/// meaningless), the totals, and the log of every judged role.
fn all_human_pairs(hs: &[&Rig]) -> (Vec<(String, Score, Score)>, [Score; 2], Log) {
    let mut totals = [Score::default(); 2];
    let mut rows = Vec::new();
    let mut log = Log::default();
    for tgt in hs {
        let (mut named, mut anon) = (Score::default(), Score::default());
        for src in hs {
            if std::ptr::eq(*src, *tgt) {
                continue;
            }
            named.add(score_pair(src, tgt, CORE, false, &mut log));
            anon.add(score_pair(src, tgt, CORE, true, &mut log));
        }
        totals[0].add(named);
        totals[1].add(anon);
        rows.push((short(&tgt.key).to_string(), named, anon));
    }
    (rows, totals, log)
}

#[test]
fn human_to_human_core_roles() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    let (rows, [all_named, all_anon], log) = all_human_pairs(&hs);
    print_table("human -> human, core roles right per target (swaps)", &rows);
    println!(
        "ALL: names {:.1}% ({} swaps), meaningless {:.1}% ({} swaps), {} pairs",
        all_named.pct(),
        all_named.swaps,
        all_anon.pct(),
        all_anon.swaps,
        hs.len() * (hs.len() - 1)
    );
    for f in &log.fails {
        println!("  {f}");
    }
    assert!(
        all_named.pct() >= 99.0,
        "names intact: {:.1}%",
        all_named.pct()
    );
    assert!(
        all_anon.pct() >= 98.0,
        "meaningless names: {:.1}%",
        all_anon.pct()
    );
    assert_eq!(all_named.swaps + all_anon.swaps, 0, "left/right swaps");
}

/// Area under the ROC curve of `confidence` as a detector of right roles: the chance that a
/// right role's confidence exceeds a wrong one's (ties count half).
fn auroc(judged: &[Judged]) -> f64 {
    let right: Vec<f32> = judged
        .iter()
        .filter(|j| j.right)
        .map(|j| j.confidence)
        .collect();
    let wrong: Vec<f32> = judged
        .iter()
        .filter(|j| !j.right)
        .map(|j| j.confidence)
        .collect();
    let mut wins = 0.0;
    for r in &right {
        for w in &wrong {
            wins += if r > w {
                1.0
            } else if r == w {
                0.5
            } else {
                0.0
            };
        }
    }
    wins / (right.len() * wrong.len()).max(1) as f64
}

/// The mapper's confidence and flags against the labels over every pair, both modes: the flags
/// hold at least 90 % of the wrong core roles and at most 5 % of the right ones, and the AUROC
/// of `confidence` is printed (`RIGCAST_ZOO_JUDGED=1` lists every judged role).
#[test]
fn flags_catch_wrong_core_roles() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    let (_, _, log) = all_human_pairs(&hs);
    let j = &log.judged;
    if std::env::var("RIGCAST_ZOO_JUDGED").is_ok() {
        for x in j {
            println!("J {} {} {:.3} {}", x.right, x.flagged, x.confidence, x.note);
        }
    }
    let count = |f: &dyn Fn(&Judged) -> bool| j.iter().filter(|x| f(x)).count();
    let (wrong, right) = (count(&|x| !x.right), count(&|x| x.right));
    let wrong_flagged = count(&|x| !x.right && x.flagged);
    let right_flagged = count(&|x| x.right && x.flagged);
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    println!(
        "core roles judged {}: wrong {wrong}, flagged {wrong_flagged} ({:.1}%); right {right}, \
         flagged {right_flagged} ({:.1}%); AUROC of confidence {:.3}",
        j.len(),
        pct(wrong_flagged, wrong),
        pct(right_flagged, right),
        auroc(j)
    );
    assert!(right > 0, "no right roles judged");
    assert!(
        wrong == 0 || auroc(j) > 0.5,
        "confidence no better than chance"
    );
    assert!(
        pct(right_flagged, right) <= 5.0,
        "right roles flagged: {:.1}%",
        pct(right_flagged, right)
    );
    assert!(
        wrong == 0 || pct(wrong_flagged, wrong) >= FLAGGED_WRONG_AT_LEAST,
        "wrong roles flagged: {:.1}%",
        pct(wrong_flagged, wrong)
    );
}

/// Prints the posture positions and roles of the file named by `RIGCAST_ZOO_DUMP` (a key
/// substring; `RIGCAST_ZOO_FOLD` folds it, `RIGCAST_ZOO_PERTURB` perturbs it as
/// [`PERTURBATIONS`] names, `RIGCAST_ZOO_ANON` renames and shuffles it as the
/// scoring does): a tool for reading a rig, not a check.
#[test]
#[ignore]
fn dump_rig() {
    let Some(dir) = data_dir() else { return };
    let Ok(want) = std::env::var("RIGCAST_ZOO_DUMP") else {
        return;
    };
    for rig in load_rigs(&dir).iter().filter(|r| r.key.contains(&want)) {
        let mut clip = if std::env::var("RIGCAST_ZOO_FOLD").is_ok() {
            folded(&rig.clip)
        } else {
            rig.clip.clone()
        };
        if let Ok(what) = std::env::var("RIGCAST_ZOO_PERTURB") {
            let f = frame_of(rig);
            let mut ed = Editable::from_clip(&clip);
            for (name, make) in PERTURBATIONS {
                if *name == what {
                    make(&mut ed, rig, &f);
                }
            }
            clip = ed.to_clip();
        }
        if std::env::var("RIGCAST_ZOO_ANON").is_ok() {
            clip = anonymise(&clip, 0x5eed ^ rig.key.len() as u64).0;
        }
        let a = analyze(&view(&clip));
        let s = &clip.skeleton;
        println!(
            "{} up={:?} fwd={:?} warnings={:?}",
            rig.key, a.up, a.forward, a.warnings
        );
        for b in s.bone_ids() {
            let p = a.positions[b.index()];
            let d = "  ".repeat(s.depth(b));
            println!(
                "{d}{:<24} {:>7.3} {:>7.3} {:>7.3}  {} ({:.2})",
                s.name(b),
                p.x,
                p.y,
                p.z,
                a.label(b),
                a.roles[b.index()].confidence
            );
        }
    }
}

/// The source roles that drive a quadruped's role by default: hind legs from legs, front legs
/// from the same side's arms (a source without hands is not scored on front feet).
fn quad_sources(role: &str) -> Vec<String> {
    let (base, side) = match role.rsplit_once('.') {
        Some((b, s)) => (b, format!(".{s}")),
        None => (role, String::new()),
    };
    let from: &[&str] = match base {
        "frontShoulder" => &["shoulder"],
        "frontUpper" => &["upperArm"],
        "frontLower" => &["lowerArm"],
        "frontFoot" => &["hand"],
        other => return vec![format!("{other}{side}")],
    };
    from.iter().map(|f| format!("{f}{side}")).collect()
}

#[test]
fn human_to_quadruped_legs() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    let quads: Vec<&Rig> = rigs.iter().filter(|r| r.kind == "quadruped").collect();
    let mut all = Score::default();
    let mut floors = Vec::new();
    for tgt in &quads {
        let mut sc = Score::default();
        let mut fails = Vec::new();
        for src in &hs {
            let table = map_rigs(src, tgt);
            let (ss, ts) = (&src.clip.skeleton, &tgt.clip.skeleton);
            for role in expand(QUAD_LEGS, &tgt.roles) {
                let accept: Vec<&String> = quad_sources(&role)
                    .iter()
                    .filter_map(|r| src.roles.get(r))
                    .flatten()
                    .collect();
                if accept.is_empty() {
                    continue;
                }
                let tb = ts.bone(&tgt.roles[&role][0]).unwrap();
                let d = driver(&table, ss, tb);
                sc.total += 1;
                if d.is_some_and(|d| accept.iter().any(|a| *a == d)) {
                    sc.right += 1;
                    continue;
                }
                let other: Vec<&String> = other_side(&role)
                    .map(|o| {
                        quad_sources(&o)
                            .iter()
                            .filter_map(|r| src.roles.get(r))
                            .flatten()
                            .collect()
                    })
                    .unwrap_or_default();
                if d.is_some_and(|d| other.iter().any(|a| *a == d)) {
                    sc.swaps += 1;
                }
                fails.push(format!(
                    "{}: {role} <- {}",
                    pair(src, tgt),
                    d.unwrap_or("-")
                ));
            }
        }
        println!(
            "{:<36} {:>6.1}% ({} swaps)",
            short(&tgt.key),
            sc.pct(),
            sc.swaps
        );
        floors.push((tgt.key.clone(), sc));
        for f in fails.iter().take(12) {
            println!("  {f}");
        }
        all.add(sc);
    }
    println!(
        "ALL quadruped legs: {:.1}% ({} swaps)",
        all.pct(),
        all.swaps
    );
    for (key, sc) in &floors {
        assert_eq!(sc.swaps, 0, "{key}: left/right swaps");
        assert!(sc.right == sc.total, "{key}: {:.1}% of leg roles", sc.pct());
    }
}

/// Source role names (without side) that count as a leg / an arm of the same side.
const LEG_ROLES: &[&str] = &["upperLeg", "lowerLeg", "foot", "toes"];
const ARM_ROLES: &[&str] = &["shoulder", "upperArm", "lowerArm", "hand"];

fn sided_names<'a>(rig: &'a Rig, roles: &[&str], side: &str) -> Vec<&'a String> {
    roles
        .iter()
        .filter_map(|r| rig.roles.get(&format!("{r}{side}")))
        .flatten()
        .collect()
}

/// T-rex: legs from legs and its small arms from arms (same side), its tail from nothing
/// (human sources have no tail).
#[test]
fn biped_creature_takes_legs_from_legs_and_arms_from_arms() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    for tgt in rigs.iter().filter(|r| r.kind == "biped_creature") {
        let ts = &tgt.clip.skeleton;
        for src in &hs {
            let table = map_rigs(src, tgt);
            let ss = &src.clip.skeleton;
            let driver_of = |t: &str| driver(&table, ss, ts.bone(t)?);
            for side in [".L", ".R"] {
                for (troles, sroles) in [(LEG_ROLES, LEG_ROLES), (ARM_ROLES, ARM_ROLES)] {
                    let allowed = sided_names(src, sroles, side);
                    let mut driven = 0;
                    for t in sided_names(tgt, &troles[..3], side) {
                        if let Some(d) = driver_of(t) {
                            assert!(
                                allowed.iter().any(|a| *a == d),
                                "{}: {t} <- {d}",
                                pair(src, tgt)
                            );
                            driven += 1;
                        }
                    }
                    assert!(driven >= 2, "{}: {side} limb barely mapped", pair(src, tgt));
                }
            }
            for t in tgt.roles.get("tail").into_iter().flatten() {
                assert_eq!(driver_of(t), None, "{}: tail {t}", pair(src, tgt));
            }
        }
    }
}

/// Spider and crab: every human maps onto them without error, and the human legs drive leg
/// bones (bones the analysis puts in ground-reaching limbs), never the body or the head.
#[test]
fn multi_legged_rigs_use_legs_for_legs() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    for tgt in rigs.iter().filter(|r| r.kind == "other") {
        let ta = analyze(&view(&tgt.clip));
        let ts = &tgt.clip.skeleton;
        for src in &hs {
            let table = map_rigs(src, tgt);
            let ss = &src.clip.skeleton;
            let legs: Vec<&String> = [".L", ".R"]
                .iter()
                .flat_map(|s| sided_names(src, LEG_ROLES, s))
                .collect();
            let mut on_legs = 0;
            for t in ts.bone_ids() {
                let Some(d) = driver(&table, ss, t) else {
                    continue;
                };
                if !legs.iter().any(|l| *l == d) {
                    continue;
                }
                let sec = ta.roles[t.index()]
                    .section
                    .map(|s| &ta.sections[s as usize]);
                assert!(
                    sec.is_some_and(|s| s.ground),
                    "{}: leg bone {d} drives {} ({})",
                    pair(src, tgt),
                    ts.name(t),
                    ta.label(t)
                );
                on_legs += 1;
            }
            assert!(
                on_legs >= 4,
                "{}: only {on_legs} leg bones used",
                pair(src, tgt)
            );
        }
    }
}

/// A hand-only rig whose joints are a flat, unparented set (WebXR): read by its joint names,
/// its side from its chirality (the labels say left); the human's left hand drives its wrist
/// and the human's fingers its fingers.
#[test]
fn flat_hand_rig_maps_by_names_and_chirality() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    for tgt in rigs.iter().filter(|r| r.kind == "hand") {
        let ts = &tgt.clip.skeleton;
        let wrist = ts.bone(&tgt.roles["hand.L"][0]).unwrap();
        let a = analyze(&view(&tgt.clip));
        assert_eq!(a.label(wrist), "left_hand", "{}", tgt.key);
        for src in hs.iter().filter(|s| s.roles.contains_key("hand.L")) {
            let table = map_rigs(src, tgt);
            let ss = &src.clip.skeleton;
            let d = driver(&table, ss, wrist);
            assert!(
                d.is_some_and(|d| src.roles["hand.L"].iter().any(|n| n == d)),
                "{} -> hand: wrist <- {d:?}",
                short(&src.key)
            );
            // Fingers, where the source has them, come from the same finger of the left hand.
            for t in ts
                .bone_ids()
                .filter(|&t| a.label(t).starts_with("left_index"))
            {
                if let Some(e) = table.entries[t.index()].as_ref() {
                    let label = analyze(&view(&src.clip)).label(e.sources[0].bone);
                    assert!(
                        label.starts_with("left_index"),
                        "{} -> {}: {label}",
                        short(&src.key),
                        ts.name(t)
                    );
                }
            }
        }
    }
}

/// The same motion on a LaFAN1 / Bandai-Namco-style skeleton: every bone's frame turned so that
/// its main child's offset lies along its local X, with zero rest rotations, so the rest pose
/// folds the body into lines and only the motion shows it. World motion is unchanged: with
/// `q_b` the turn of bone `b`, offsets become `q_p⁻¹ · t_b` and local rotations
/// `q_p⁻¹ · r_b · q_b`.
fn folded(clip: &Clip) -> Clip {
    use glam::{Quat, Vec3};
    let skel = &clip.skeleton;
    let turn: Vec<Quat> = skel
        .bone_ids()
        .map(|b| {
            let main = skel
                .children(b)
                .iter()
                .max_by_key(|c| {
                    let s = c.index();
                    (
                        skel.bone_ids()
                            .filter(|d| is_below(skel, *d, BoneId(s as u16)))
                            .count(),
                        s,
                    )
                })
                .copied();
            match main.map(|c| skel.rest()[c.index()].translation.normalize_or_zero()) {
                Some(d) if d != Vec3::ZERO => Quat::from_rotation_arc(Vec3::X, d),
                _ => Quat::IDENTITY,
            }
        })
        .collect();
    let parent_turn = |b: BoneId| {
        skel.parent(b)
            .map(|p| turn[p.index()])
            .unwrap_or(Quat::IDENTITY)
    };
    let mut raw = skel.to_raw();
    for b in skel.bone_ids() {
        let qp = parent_turn(b).inverse();
        raw.bones[b.index()].rest =
            rigcast_retarget::Transform::from_translation(qp * skel.rest()[b.index()].translation);
    }
    let poses = clip
        .poses
        .iter()
        .map(|p| Pose {
            rotations: skel
                .bone_ids()
                .map(|b| {
                    (parent_turn(b).inverse() * p.rotations[b.index()] * turn[b.index()])
                        .normalize()
                })
                .collect(),
            translations: skel
                .bone_ids()
                .map(|b| parent_turn(b).inverse() * p.translations[b.index()])
                .collect(),
        })
        .collect();
    rebuilt(clip, &raw, poses)
}

fn is_below(skel: &Skeleton, mut b: BoneId, ancestor: BoneId) -> bool {
    loop {
        if b == ancestor {
            return true;
        }
        match skel.parent(b) {
            Some(p) => b = p,
            None => return false,
        }
    }
}

/// `clip` with the skeleton `raw` and `poses` on it.
fn rebuilt(clip: &Clip, raw: &RawSkeleton, poses: Vec<Pose>) -> Clip {
    let skeleton = Skeleton::build(raw).unwrap();
    Clip::new(
        clip.name.clone(),
        std::sync::Arc::new(skeleton),
        poses,
        clip.frame_time_secs,
    )
    .unwrap()
}

/// A way of rebuilding a clip (folded, turned).
type Variant<'a> = &'a dyn Fn(&Clip) -> Clip;

/// The clip turned as a whole by `g` (rest and every frame of the root).
fn turned(clip: &Clip, g: glam::Quat) -> Clip {
    let skel = &clip.skeleton;
    let mut raw = skel.to_raw();
    for b in skel.roots() {
        let r = &mut raw.bones[b.index()].rest;
        r.translation = g * r.translation;
        r.rotation = g * r.rotation;
    }
    let roots: Vec<BoneId> = skel.roots().collect();
    let poses = clip
        .poses
        .iter()
        .map(|p| {
            let mut p = p.clone();
            for &b in &roots {
                p.translations[b.index()] = g * p.translations[b.index()];
                p.rotations[b.index()] = g * p.rotations[b.index()];
            }
            p
        })
        .collect();
    rebuilt(clip, &raw, poses)
}

/// Every labelled human with animation, folded LaFAN1-style, still maps from every other
/// human; every labelled human turned Z-up (and turned arbitrarily) maps as before.
#[test]
fn folded_rests_and_turned_rigs_map_like_the_originals() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    let z_up = glam::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let odd = glam::Quat::from_axis_angle(glam::Vec3::new(0.3, 1.0, 0.2).normalize_or_zero(), 2.3)
        * glam::Quat::from_rotation_x(0.35);
    let variants: [(&str, Variant); 3] = [
        ("folded", &|c: &Clip| folded(c)),
        ("z-up", &|c: &Clip| turned(c, z_up)),
        ("turned", &|c: &Clip| turned(c, odd)),
    ];
    for (what, make) in variants {
        let mut total = Score::default();
        let mut log = Log::default();
        for tgt in &hs {
            if what == "folded" && tgt.clip.poses.len() < 2 {
                continue;
            }
            let changed = Rig {
                key: tgt.key.clone(),
                kind: tgt.kind.clone(),
                clip: make(&tgt.clip),
                roles: tgt.roles.clone(),
            };
            let mut row = Score::default();
            for src in &hs {
                if std::ptr::eq(*src, *tgt) {
                    continue;
                }
                row.add(score_pair(src, &changed, CORE, false, &mut log));
            }
            println!(
                "  {what} {:<28} {:>6.1}% ({} swaps)",
                short(&tgt.key),
                row.pct(),
                row.swaps
            );
            total.add(row);
        }
        println!("{what}: {:.1}% ({} swaps)", total.pct(), total.swaps);
        for f in log.fails.iter().take(30) {
            println!("  {f}");
        }
        assert_eq!(total.swaps, 0, "{what}: swaps");
        assert!(total.pct() >= 97.0, "{what}: {:.1}%", total.pct());
    }
}

/// kinect2 is broken on purpose (offsets shifted one level, joints stacked, motion all zero):
/// it loads, and maps by its names, as target and as source, from and to every other human.
#[test]
fn broken_geometry_maps_by_names() {
    let Some(rigs) = real_rigs() else { return };
    let Some(broken) = rigs.iter().find(|r| r.key.contains("kinect2")) else {
        println!("SKIP: no kinect2 rig in the labels");
        return;
    };
    let a = analyze(&view(&broken.clip));
    assert!(
        a.warnings.iter().any(|w| w.contains("names")),
        "{:?}",
        a.warnings
    );
    let (mut into, mut from) = (Score::default(), Score::default());
    let mut log = Log::default();
    for other in humans(&rigs) {
        into.add(score_pair(other, broken, CORE, false, &mut log));
        from.add(score_pair(broken, other, CORE, false, &mut log));
    }
    println!(
        "kinect2 as target {:.1}% ({} swaps), as source {:.1}% ({} swaps)",
        into.pct(),
        into.swaps,
        from.pct(),
        from.swaps
    );
    for f in log.fails.iter().take(20) {
        println!("  {f}");
    }
    assert_eq!(into.swaps + from.swaps, 0);
    assert!(into.pct() >= 97.0 && from.pct() >= 97.0);
}

#[path = "common/perturb.rs"]
mod perturb;
use perturb::Editable;

/// What a perturbation needs to know of a labelled rig: its axes and height as the analysis
/// reads its named original (names intact: 0 swaps there), and the frame it read.
struct Frame {
    up: glam::Vec3,
    forward: glam::Vec3,
    left: glam::Vec3,
    /// Hips to head joint: the scale of what is added (a cartoon's head top or a tall hat
    /// would make the whole height a poor one).
    torso: f32,
    frame: Option<usize>,
}

fn frame_of(rig: &Rig) -> Frame {
    let a = analyze(&view(&rig.clip));
    let skel = &rig.clip.skeleton;
    let at = |role: &str| {
        let b = skel.bone(rig.roles.get(role)?.first()?)?;
        Some(a.positions[b.index()])
    };
    let torso = match (at("hips"), at("head")) {
        (Some(h), Some(t)) => (t - h).length(),
        _ => 0.3 * a.size,
    };
    Frame {
        up: a.up,
        forward: a.forward,
        left: a.left,
        torso: torso.max(1e-3),
        frame: a.posture_frame,
    }
}

/// The editable index of the first bone labelled `role`.
fn labelled(ed: &Editable, rig: &Rig, role: &str) -> Option<usize> {
    ed.index(rig.roles.get(role)?.first()?)
}

/// A backpack chain hanging behind the chest and two ribbons behind the head, sized by the
/// torso (`t`: the pack 0.3 t behind and 0.8 t tall, ribbons of 0.66 t).
fn add_backpack(ed: &mut Editable, rig: &Rig, f: &Frame) {
    let t = f.torso;
    if let Some(chest) = labelled(ed, rig, "chest").or_else(|| labelled(ed, rig, "spine")) {
        let mut p = ed.add_world(chest, "x_pack", -f.forward * 0.3 * t, f.frame);
        for i in 0..2 {
            p = ed.add_world(p, &format!("x_pack{i}"), -f.up * 0.4 * t, f.frame);
        }
    }
    if let Some(head) = labelled(ed, rig, "head") {
        for s in [-1.0f32, 1.0] {
            let off = -f.forward * 0.2 * t + f.left * s * 0.13 * t;
            let mut p = ed.add_world(head, &format!("x_ribbon{s}"), off, f.frame);
            for i in 0..3 {
                p = ed.add_world(p, &format!("x_ribbon{s}_{i}"), -f.up * 0.22 * t, f.frame);
            }
        }
    }
}

/// Limb segments and the bone that ends each (whose offset is the segment).
const SEGMENTS: &[(&str, &str)] = &[
    ("upperArm", "lowerArm"),
    ("lowerArm", "hand"),
    ("upperLeg", "lowerLeg"),
    ("lowerLeg", "foot"),
];

/// The labelled bone `end` and the segment bone it ends, when `end` hangs from that bone (an
/// IK foot under the root, as RobotExpressive's, ends no segment: its offset is not the shin).
fn segment(ed: &Editable, rig: &Rig, seg: &str, end: &str) -> Option<(usize, usize)> {
    let (b, e) = (labelled(ed, rig, seg)?, labelled(ed, rig, end)?);
    (ed.raw.bones[e].parent == Some(b)).then_some((b, e))
}

/// UE-style twist leaves halfway along every limb segment.
fn add_twist_leaves(ed: &mut Editable, rig: &Rig) {
    for s in [".L", ".R"] {
        for (seg, end) in SEGMENTS {
            let Some((b, e)) = segment(ed, rig, &format!("{seg}{s}"), &format!("{end}{s}")) else {
                continue;
            };
            let off = ed.raw.bones[e].rest.translation * 0.5;
            ed.add_child(b, &format!("x_twist_{seg}{s}"), off);
        }
    }
}

/// Daz-style twist bones in the chain: each arm segment split in two.
fn add_twist_chain(ed: &mut Editable, rig: &Rig) {
    for s in [".L", ".R"] {
        for end in ["lowerArm", "hand"] {
            if let Some(e) = labelled(ed, rig, &format!("{end}{s}")) {
                ed.insert_above(e, &format!("x_tw_{end}{s}"), 0.5);
            }
        }
    }
}

/// Zero-length helpers: a pelvis on the hips' joint above it, thigh helpers on the hips'
/// joint, a one-sided deltoid helper on the left upper arm, a zero-length leaf on the head.
fn add_helpers(ed: &mut Editable, rig: &Rig) {
    if let Some(h) = labelled(ed, rig, "hips") {
        ed.insert_above(h, "x_pelvis", 1.0);
    }
    for s in [".L", ".R"] {
        if let Some(t) = labelled(ed, rig, &format!("upperLeg{s}")) {
            ed.insert_above(t, &format!("x_thighroot{s}"), 0.0);
        }
    }
    if let (Some(u), Some(l)) = (
        labelled(ed, rig, "upperArm.L"),
        labelled(ed, rig, "lowerArm.L"),
    ) {
        let off = ed.raw.bones[l].rest.translation * 0.15;
        ed.add_child(u, "x_deltoid", off);
    }
    if let Some(h) = labelled(ed, rig, "head") {
        ed.add_child(h, "x_headhelper", glam::Vec3::ZERO);
    }
}

/// A scapula bone halfway between each clavicle (or whatever the arm hangs from) and the arm.
fn add_scapulae(ed: &mut Editable, rig: &Rig) {
    for s in [".L", ".R"] {
        if let Some(u) = labelled(ed, rig, &format!("upperArm{s}")) {
            ed.insert_above(u, &format!("x_scapula{s}"), 0.5);
        }
    }
}

/// A cartoon: the head grown (neck 1.4×, everything above the head 2.5×), the legs shortened
/// (thighs and shins 0.55×) with the hips lowered as much, so the feet still stand where they
/// stood (a rig whose root sits on the floor keeps it there; a leg ending in an IK foot under
/// the root, whose shin is no bone, keeps its length).
fn make_cartoon(ed: &mut Editable, rig: &Rig, f: &Frame) {
    if let Some(h) = labelled(ed, rig, "head") {
        ed.scale_offset(h, 1.4);
        for b in ed.below(h) {
            ed.scale_offset(b, 2.5);
        }
    }
    let mut drop = 0.0f32;
    for s in [".L", ".R"] {
        let segs: Option<Vec<(usize, usize)>> = [("upperLeg", "lowerLeg"), ("lowerLeg", "foot")]
            .iter()
            .map(|(seg, end)| segment(ed, rig, &format!("{seg}{s}"), &format!("{end}{s}")))
            .collect();
        let mut lost = 0.0;
        for (_, b) in segs.unwrap_or_default() {
            lost += 0.45 * ed.raw.bones[b].rest.translation.length();
            ed.scale_offset(b, 0.55);
        }
        drop = drop.max(lost);
    }
    if let Some(h) = labelled(ed, rig, "hips") {
        ed.shift(h, -f.up * drop, f.frame);
    }
}

/// The rig facing the other way: turned half a turn about its up axis.
fn face_back(ed: &mut Editable, f: &Frame) {
    ed.turn(glam::Quat::from_axis_angle(f.up, std::f32::consts::PI));
}

/// A perturbation of a labelled rig: its name and how to make it.
type Perturbation = (&'static str, fn(&mut Editable, &Rig, &Frame));

const PERTURBATIONS: &[Perturbation] = &[
    ("backpack", |ed, rig, f| add_backpack(ed, rig, f)),
    ("twist", |ed, rig, _| add_twist_leaves(ed, rig)),
    ("twist-chain", |ed, rig, _| add_twist_chain(ed, rig)),
    ("helpers", |ed, rig, _| add_helpers(ed, rig)),
    ("scapula", |ed, rig, _| add_scapulae(ed, rig)),
    ("cartoon", |ed, rig, f| make_cartoon(ed, rig, f)),
    ("static", |ed, _, f| ed.make_static(f.frame)),
    ("faces-back", |ed, _, f| face_back(ed, f)),
    ("avatar", |ed, rig, f| {
        add_backpack(ed, rig, f);
        add_helpers(ed, rig);
        ed.make_static(f.frame);
        face_back(ed, f);
    }),
];

/// The sources the perturbed targets are mapped from: every human, or every `k`-th with
/// `RIGCAST_ZOO_SOURCE_STEP=k` (a quicker look).
fn perturbation_sources<'a>(hs: &[&'a Rig]) -> Vec<&'a Rig> {
    let step = std::env::var("RIGCAST_ZOO_SOURCE_STEP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1usize)
        .max(1);
    hs.iter().step_by(step).copied().collect()
}

/// Every labelled human, perturbed as unseen families differ (backpack and ribbons, twist
/// bones, zero-length helpers, scapulae, cartoon proportions, no animation, facing the other
/// way, and all of a static avatar's at once), with meaningless names and shuffled children,
/// mapped from every other human: the same core roles, no swaps, and the flags catch the wrong
/// ones. Prints the table per perturbation and rig, and the confidence rates over them.
#[test]
fn perturbed_rigs_keep_their_core_roles() {
    let Some(rigs) = real_rigs() else { return };
    let hs = humans(&rigs);
    let sources = perturbation_sources(&hs);
    let mut log = Log::default();
    let mut totals = Vec::new();
    let mut fails = Vec::new();
    print!(
        "\nperturbed targets, meaningless names, core roles right (swaps)\n{:<24}",
        "target"
    );
    for (what, _) in PERTURBATIONS {
        print!(" {what:>12}");
    }
    println!();
    let mut sums = vec![Score::default(); PERTURBATIONS.len()];
    let mut per_kind: Vec<Vec<Judged>> = vec![Vec::new(); PERTURBATIONS.len()];
    for tgt in &hs {
        let f = frame_of(tgt);
        print!("{:<24}", short(&tgt.key));
        for (k, (what, make)) in PERTURBATIONS.iter().enumerate() {
            let mut ed = Editable::from_clip(&tgt.clip);
            make(&mut ed, tgt, &f);
            let changed = Rig {
                key: tgt.key.clone(),
                kind: tgt.kind.clone(),
                clip: ed.to_clip(),
                roles: tgt.roles.clone(),
            };
            let mut row = Score::default();
            let mut plog = Log::default();
            for src in sources.iter().filter(|s| !std::ptr::eq(**s, *tgt)) {
                row.add(score_pair(src, &changed, CORE, true, &mut plog));
            }
            print!(" {:>8.1}% {:>2}", row.pct(), row.swaps);
            fails.extend(plog.fails.into_iter().map(|l| format!("{what}: {l}")));
            if std::env::var("RIGCAST_ZOO_JUDGED").is_ok() {
                for x in &plog.judged {
                    println!(
                        "J {what} {} {} {} {:.3} {}",
                        short(&tgt.key),
                        x.right,
                        x.flagged,
                        x.confidence,
                        x.note
                    );
                }
            }
            per_kind[k].extend(plog.judged.iter().cloned());
            log.judged.extend(plog.judged);
            sums[k].add(row);
        }
        println!();
    }
    print!("{:<24}", "ALL");
    for (k, (what, _)) in PERTURBATIONS.iter().enumerate() {
        print!(" {:>8.1}% {:>2}", sums[k].pct(), sums[k].swaps);
        totals.push((*what, sums[k]));
    }
    println!();
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    println!("per perturbation: wrong roles, of them flagged; right roles flagged; AUROC");
    for ((what, _), j) in PERTURBATIONS.iter().zip(&per_kind) {
        let (wrong, right, wrong_flagged, right_flagged) = flag_rates(j);
        println!(
            "{what:<12} wrong {wrong:>4}, flagged {:>5.1}%; right flagged {:>4.1}%; AUROC {:.3}",
            pct(wrong_flagged, wrong),
            pct(right_flagged, right),
            auroc(j)
        );
    }
    let (wrong, right, wrong_flagged, right_flagged) = flag_rates(&log.judged);
    println!(
        "perturbed core roles judged {}: wrong {wrong}, flagged {wrong_flagged} ({:.1}%); right \
         {right}, flagged {right_flagged} ({:.1}%); AUROC of confidence {:.3}",
        log.judged.len(),
        pct(wrong_flagged, wrong),
        pct(right_flagged, right),
        auroc(&log.judged)
    );
    for l in &fails {
        println!("  {l}");
    }
    if sources.len() < hs.len() {
        println!("bounds not checked: RIGCAST_ZOO_SOURCE_STEP maps from some sources only");
        return;
    }
    for (what, sc) in &totals {
        assert_eq!(sc.swaps, 0, "{what}: left/right swaps");
        assert!(sc.pct() >= HELD, "{what}: {:.1}% < {HELD}%", sc.pct());
    }
    // The flags: no more right roles flagged than the issue allows, and no fewer wrong ones.
    assert!(pct(right_flagged, right) <= 5.0);
    assert!(pct(wrong_flagged, wrong) >= FLAGGED_WRONG_AT_LEAST);
}

/// Per perturbation, the share of core roles held: the 98 % for meaningless names,
/// with no left/right swaps (today every perturbation holds 99.2 % or more).
const HELD: f64 = 98.0;

/// Wrong core roles that the flags must catch, percent: the bound (today 100 % of
/// the perturbed rigs' and of the clean pairs').
const FLAGGED_WRONG_AT_LEAST: f64 = 90.0;

/// (wrong, right, wrong flagged, right flagged) over judged roles.
fn flag_rates(j: &[Judged]) -> (usize, usize, usize, usize) {
    let count = |f: &dyn Fn(&Judged) -> bool| j.iter().filter(|x| f(x)).count();
    (
        count(&|x| !x.right),
        count(&|x| x.right),
        count(&|x| !x.right && x.flagged),
        count(&|x| x.right && x.flagged),
    )
}
