//! `rigcast retarget` onto every labelled human rig in the shared data gives back that rig:
//! re-read with parsers written here (not rigcast's readers), the output's hierarchy is the
//! target file's exactly.
//! - BVH: joint names, order and nesting, End Sites (still End Sites), OFFSETs, channel counts
//!   and orders; every motion line has the target's channel count.
//! - GLB: every node's name and children, each skin's joint order and inverse bind matrices
//!   (the bytes), the meshes; one animation whose channels target the skin's nodes.
#![allow(clippy::unwrap_used)]

mod common;

#[path = "common/retarget_cli.rs"]
mod retarget_cli;

use std::path::{Path, PathBuf};

use retarget_cli::{run, RetargetArgs};
use serde_json::Value;

/// One line of a BVH hierarchy as this test reads it.
#[derive(Debug, Clone, PartialEq)]
enum Entry {
    Open { keyword: String, name: String },
    EndSite,
    Offset([f32; 3]),
    Channels(Vec<String>),
    Close,
}

/// The HIERARCHY part of a BVH file, token by token; and the motion lines' value counts.
fn bvh_hierarchy(text: &str) -> (Vec<Entry>, Vec<usize>) {
    let mut entries = Vec::new();
    let mut lines = text.lines();
    for line in lines.by_ref() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("MOTION") => break,
            Some(k @ ("ROOT" | "JOINT")) => entries.push(Entry::Open {
                keyword: k.to_string(),
                name: words.collect::<Vec<_>>().join(" "),
            }),
            Some("End") => entries.push(Entry::EndSite),
            Some("OFFSET") => {
                let v: Vec<f32> = words.map(|w| w.parse().unwrap()).collect();
                entries.push(Entry::Offset([v[0], v[1], v[2]]));
            }
            Some("CHANNELS") => {
                let n: usize = words.next().unwrap().parse().unwrap();
                let names: Vec<String> = words.map(str::to_string).collect();
                assert_eq!(names.len(), n, "CHANNELS count");
                entries.push(Entry::Channels(names));
            }
            Some("}") => entries.push(Entry::Close),
            _ => {}
        }
    }
    let counts = lines
        .filter(|l| !l.trim().is_empty() && !l.starts_with("Frame"))
        .map(|l| l.split_whitespace().count())
        .collect();
    (entries, counts)
}

/// The JSON chunk and the binary chunk of a GLB.
fn glb_chunks(bytes: &[u8]) -> (Value, Vec<u8>) {
    assert_eq!(&bytes[0..4], b"glTF");
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let at = 20 + json_len;
    let bin = if at + 8 <= bytes.len() {
        let len = u32_at(at);
        bytes[at + 8..at + 8 + len].to_vec()
    } else {
        Vec::new()
    };
    (json, bin)
}

/// The floats of an accessor (tightly packed views only, as inverse bind matrices are).
fn accessor_floats(json: &Value, bin: &[u8], index: usize) -> Vec<f32> {
    let a = &json["accessors"][index];
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    assert_eq!(view["buffer"].as_u64().unwrap_or(0), 0, "GLB buffer 0 only");
    let offset = view["byteOffset"].as_u64().unwrap_or(0) + a["byteOffset"].as_u64().unwrap_or(0);
    let count = a["count"].as_u64().unwrap() * 16;
    (0..count)
        .map(|k| {
            let o = (offset + 4 * k) as usize;
            f32::from_le_bytes(bin[o..o + 4].try_into().unwrap())
        })
        .collect()
}

fn compare_glb(target: &Path, out: &Path) {
    let (tj, tb) = glb_chunks(&std::fs::read(target).unwrap());
    let (oj, ob) = glb_chunks(&std::fs::read(out).unwrap());
    let nodes = |j: &Value| -> Vec<(Option<String>, Value)> {
        j["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| {
                (
                    n["name"].as_str().map(str::to_string),
                    n["children"].clone(),
                )
            })
            .collect()
    };
    assert_eq!(nodes(&tj), nodes(&oj), "nodes (names, children)");
    assert_eq!(tj["meshes"], oj["meshes"], "meshes");
    let (ts, os) = (
        tj["skins"].as_array().unwrap(),
        oj["skins"].as_array().unwrap(),
    );
    assert_eq!(ts.len(), os.len(), "skins");
    for (t, o) in ts.iter().zip(os) {
        assert_eq!(t["joints"], o["joints"], "skin joint order");
        if let Some(ti) = t["inverseBindMatrices"].as_u64() {
            let oi = o["inverseBindMatrices"]
                .as_u64()
                .expect("inverse bind matrices kept");
            assert_eq!(
                accessor_floats(&tj, &tb, ti as usize),
                accessor_floats(&oj, &ob, oi as usize),
                "inverse bind matrices"
            );
        }
    }
    let anims = oj["animations"].as_array().unwrap();
    assert_eq!(anims.len(), 1, "one animation");
    let joints: Vec<u64> = ts[0]["joints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j.as_u64().unwrap())
        .collect();
    let animated: Vec<u64> = anims[0]["channels"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["target"]["path"] == "rotation")
        .map(|c| c["target"]["node"].as_u64().unwrap())
        .collect();
    assert!(
        joints.iter().all(|j| animated.contains(j)),
        "every skin joint gets a rotation channel"
    );
}

fn compare_bvh(target: &Path, out: &Path, frames: usize) {
    let (t, _) = bvh_hierarchy(&std::fs::read_to_string(target).unwrap());
    let (o, counts) = bvh_hierarchy(&std::fs::read_to_string(out).unwrap());
    assert_eq!(t.len(), o.len(), "hierarchy length");
    for (k, (a, b)) in t.iter().zip(&o).enumerate() {
        assert_eq!(a, b, "hierarchy entry {k}");
    }
    let channels: usize = t
        .iter()
        .map(|e| match e {
            Entry::Channels(c) => c.len(),
            _ => 0,
        })
        .sum();
    assert_eq!(counts.len(), frames, "motion lines");
    assert!(
        counts.iter().all(|&c| c == channels),
        "values per motion line"
    );
}

/// Angle between two rotations (q ≡ −q) from the chord in f64: `acos` of an f32 dot product
/// cannot resolve angles below ~1e-3 rad.
fn angle(a: glam::Quat, b: glam::Quat) -> f32 {
    let (a, b) = (
        glam::Vec4::from(a).as_dvec4(),
        glam::Vec4::from(b).as_dvec4(),
    );
    let chord = (a - b).length().min((a + b).length());
    (4.0 * (chord / 2.0).min(1.0).asin()) as f32
}

fn labelled_humans(root: &Path) -> Vec<PathBuf> {
    common::all_labels(root)
        .iter()
        .filter(|(_, v)| v["kind"] == "human")
        .map(|(k, _)| root.join(k))
        .collect()
}

#[test]
fn retargeting_onto_every_labelled_human_keeps_its_exact_hierarchy() {
    // The first labelled walk (found by its motion): one source, onto every labelled human.
    let (Some(root), Some((walk, source, _))) = (
        common::shared_data("labels.json").and_then(|p| p.parent().map(Path::to_path_buf)),
        common::first_walk(),
    ) else {
        return;
    };
    let anim = walk.path;
    let dir = std::env::temp_dir().join(format!("rigcast-hierarchy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let targets = labelled_humans(&root);
    assert!(
        targets.len() >= 10,
        "only {} labelled humans",
        targets.len()
    );
    for target in targets {
        let ext = target
            .extension()
            .unwrap()
            .to_str()
            .unwrap()
            .to_ascii_lowercase();
        let out_ext = if ext == "bvh" { "bvh" } else { "glb" };
        let stem = target.file_stem().unwrap().to_str().unwrap();
        let out = dir.join(format!("{stem}.{out_ext}"));
        run(&RetargetArgs {
            anim: anim.clone(),
            target: target.clone(),
            output: out.clone(),
            mapping: None,
            fps: None,
            in_place: false,
            no_foot_lock: false,
        })
        .unwrap_or_else(|e| panic!("{}: {e:#}", target.display()));
        if out_ext == "bvh" {
            compare_bvh(&target, &out, source.num_frames());
        } else {
            compare_glb(&target, &out);
        }
        // rigcast reads the output back as the target's skeleton, with the motion the same
        // retarget gives in a recording (exact floats): writing onto the rig lost nothing.
        let back = rigcast_sources::load_clip(&out).unwrap();
        let exact = dir.join(format!("{stem}.rcr"));
        run(&RetargetArgs {
            anim: anim.clone(),
            target: target.clone(),
            output: exact.clone(),
            mapping: None,
            fps: None,
            in_place: false,
            no_foot_lock: false,
        })
        .unwrap();
        let exact = rigcast_sources::load_clip(&exact).unwrap();
        let mut worst_m = 0.0f32;
        for (a, b) in back.poses.iter().zip(&exact.poses) {
            for (ta, tb) in a.translations.iter().zip(&b.translations) {
                worst_m = worst_m.max((*ta - *tb).length());
            }
        }
        // End Sites carry no channels: their rotation is not written (nothing hangs below).
        let leaves_only = |i: usize| {
            back.skeleton
                .children(rigcast_retarget::BoneId(i as u16))
                .is_empty()
        };
        let mut worst_inner = 0.0f32;
        for (a, b) in back.poses.iter().zip(&exact.poses) {
            for (i, (qa, qb)) in a.rotations.iter().zip(&b.rotations).enumerate() {
                if !(out_ext == "bvh" && leaves_only(i)) {
                    worst_inner = worst_inner.max(angle(*qa, *qb));
                }
            }
        }
        println!(
            "{}: motion read back differs by ≤ {:.2e} rad (inner joints), {:.2e} m",
            target.display(),
            worst_inner,
            worst_m
        );
        assert!(
            worst_inner < 1e-5,
            "{}: rotations off by {worst_inner} rad",
            target.display()
        );
        assert!(
            worst_m < 1e-5,
            "{}: translations off by {worst_m} m",
            target.display()
        );
        let want = rigcast_sources::load_clip(&target).unwrap().skeleton;
        assert_eq!(back.skeleton.names(), want.names(), "{}", target.display());
        assert_eq!(
            back.skeleton.parents(),
            want.parents(),
            "{}",
            target.display()
        );
        assert_eq!(
            back.num_frames(),
            source.num_frames(),
            "{}",
            target.display()
        );
        println!(
            "{}: hierarchy kept ({} bones)",
            target.display(),
            want.num_bones()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
