//! Seeded garbled input for the mapping file parser and the mapping cache decoder: each answers
//! with an error (or `None`), never a panic, and whatever they accept flows through
//! `apply_overrides`, `Mapping::build` and one `apply` without panicking either.
//!
//! Inputs are mutations of a real mapping file / cache entry (byte flips, cuts, splices,
//! inserted noise), so the parsers get past their first check. A fixed xorshift makes a failure
//! reproduce with the printed case number.
#![allow(clippy::unwrap_used)] // tests may unwrap

use rigcast_retarget::analysis::SkeletonView;
use rigcast_retarget::corpus;
use rigcast_retarget::mapping::file::mapping_file_to_string;
use rigcast_retarget::mapping::{
    apply_overrides, auto_map, cache, parse_mapping_file, to_mapping_file, CacheKey, MapOptions,
    MappingFileError, MappingTable,
};
use rigcast_retarget::{BoneId, Mapping, RetargetOptions, Skeleton};

const CASES: usize = 3000;

#[path = "common/xorshift.rs"]
mod xorshift;
use xorshift::Rng;

/// One to four random edits of `seed`; the bytes written are ones that matter to TOML/JSON.
fn mutate(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    const SPECIAL: &[u8] = b"\"'[]{}=,.:#\n\\-0123456789eEnNaif ";
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(b.len() + 1);
        match rng.below(4) {
            0 if !b.is_empty() => {
                let i = at.min(b.len() - 1);
                b[i] = SPECIAL[rng.below(SPECIAL.len())];
            }
            1 => b.truncate(at),
            2 if at < b.len() => {
                let end = (at + 1 + rng.below(40)).min(b.len());
                let span = b[at..end].to_vec();
                let to = rng.below(b.len() + 1);
                b.splice(to..to, span);
            }
            _ => {
                let noise: Vec<u8> = (0..1 + rng.below(6))
                    .map(|_| SPECIAL[rng.below(SPECIAL.len())])
                    .collect();
                b.splice(at..at, noise);
            }
        }
    }
    b
}

struct Fixture {
    src: Skeleton,
    tgt: Skeleton,
    table: MappingTable,
}

fn fixture() -> Fixture {
    let src = corpus::get("mixamo").unwrap().skeleton;
    let tgt = corpus::get("vrm_anon").unwrap().skeleton;
    let table = auto_map(
        &SkeletonView::rest(&src),
        &SkeletonView::rest(&tgt),
        &MapOptions::default(),
    );
    Fixture { src, tgt, table }
}

/// Builds and runs one frame; a bad table must be an error from `build`, not a panic later.
fn build_and_apply(f: &Fixture, table: &MappingTable) -> bool {
    let Ok(mut m) = Mapping::build(&[&f.src], &f.tgt, table, &RetargetOptions::default()) else {
        return false;
    };
    let mut out = m.new_target_pose();
    m.apply_one(&f.src.rest_pose(), &mut out).unwrap();
    assert!(out.rotations.iter().all(|q| q.is_finite()));
    true
}

#[test]
fn mapping_file_parser_never_panics() {
    let f = fixture();
    let full = mapping_file_to_string(&to_mapping_file(&f.table, &[&f.src], &f.tgt));
    // A short hand-written file using every field (names from the fixture skeletons).
    let (t0, t1) = (
        f.tgt.name(f.tgt.bone_ids().nth(1).unwrap()),
        f.tgt.name(f.tgt.bone_ids().nth(2).unwrap()),
    );
    let (s0, s1) = (
        f.src.name(f.src.bone_ids().nth(1).unwrap()),
        f.src.name(f.src.bone_ids().nth(2).unwrap()),
    );
    let small = format!(
        "version = 1\n[bones.\"{t0}\"]\nsource = \"{s0}\"\ndelay_secs = 0.2\nreverse = true\nweight = 0.5\n\
         [bones.\"{t1}\"]\nsources = [ {{ bone = \"{s0}\", weight = 0.5 }}, {{ bone = \"{s1}\", input = 0, weight = 0.5 }} ]\n"
    );
    let seeds = [full.as_bytes(), small.as_bytes()];
    let mut rng = Rng(0x0123_4567_89ab_cdef);
    let (mut parsed, mut applied, mut built, mut rejected) = (0, 0, 0, 0);
    for case in 0..CASES {
        let seed = seeds[case % 2];
        let text = String::from_utf8_lossy(&mutate(&mut rng, seed)).into_owned();
        let file = match parse_mapping_file(&text) {
            Ok(file) => file,
            Err(e) => {
                assert!(!e.to_string().is_empty());
                rejected += 1;
                continue;
            }
        };
        parsed += 1;
        let mut table = f.table.clone();
        if apply_overrides(&mut table, &file, &[&f.src], &f.tgt).is_err() {
            // A refused file leaves the table untouched.
            assert_eq!(table, f.table, "case {case}");
            continue;
        }
        applied += 1;
        built += build_and_apply(&f, &table) as usize;
    }
    println!("parsed {parsed} applied {applied} built {built} rejected {rejected}");
    assert!(parsed > 0 && applied > 0 && built > 0 && rejected > CASES / 4);
}

#[test]
fn apply_overrides_refuses_a_table_for_another_skeleton() {
    let f = fixture();
    let file = parse_mapping_file(&mapping_file_to_string(&to_mapping_file(
        &f.table,
        &[&f.src],
        &f.tgt,
    )))
    .unwrap();
    let mut short = MappingTable::empty(3);
    let err = apply_overrides(&mut short, &file, &[&f.src], &f.tgt).unwrap_err();
    assert!(
        matches!(err, MappingFileError::TableSize { entries: 3, bones } if bones == f.tgt.num_bones()),
        "{err}"
    );
    assert_eq!(short, MappingTable::empty(3));
}

#[test]
fn cache_decode_never_panics() {
    let f = fixture();
    let key = CacheKey::new(&[&f.src], &f.tgt, &MapOptions::default());
    let text = cache::encode(&key, &f.table);
    assert_eq!(cache::decode(&text, &key), Some(f.table.clone()));
    let mut rng = Rng(0xfeed_face_dead_beef);
    let (mut decoded, mut built, mut missed) = (0, 0, 0);
    for _ in 0..CASES {
        let text = String::from_utf8_lossy(&mutate(&mut rng, text.as_bytes())).into_owned();
        match cache::decode(&text, &key) {
            None => missed += 1,
            Some(table) => {
                decoded += 1;
                // Decoded tables can still hold out-of-range bones or bad weights; `build`
                // validates them.
                built += build_and_apply(&f, &table) as usize;
            }
        }
    }
    println!("decoded {decoded} built {built} missed {missed}");
    assert!(decoded > 0 && missed > CASES / 4);

    // An entry with the right key whose table points past the source skeleton (a corrupt or
    // hand-edited file) decodes, and `build` refuses it instead of indexing out of bounds.
    let mut corrupt = f.table.clone();
    let entry = corrupt.entries.iter_mut().flatten().next().unwrap();
    entry.sources[0].bone = BoneId(60_000);
    let table = cache::decode(&cache::encode(&key, &corrupt), &key).unwrap();
    assert!(Mapping::build(&[&f.src], &f.tgt, &table, &RetargetOptions::default()).is_err());
}
