//! The shared real test data (`../shared/data` beside the workspace), which the project may not
//! redistribute: tests that read it skip with a printed reason when it is absent. Included by
//! path in the tests and benches of several crates (`sources/tests`, `sources/benches`,
//! `server/tests`, the server's unit tests, `tests/src/lib.rs`); every crate folder sits one
//! level below the workspace, so the same relative path finds the data from each of them.
#![allow(dead_code)]

use std::path::PathBuf;

/// The CMU walk (mocap, 31 joints, MotionBuilder names).
pub const CMU_WALK: &str = "bvh/cmu_131_01_walk.bvh";
/// An upper body with a sparse spine and a head, no legs to speak of (PyMO's Meredith).
pub const MEREDITH: &str = "zoo/bvh/sparse_spine_head__pymo_meredith.bvh";
/// Godot's platformer robot, which names its left side `r-*`.
pub const GODOT_ROBOT: &str = "zoo/gltf/godot_robot__platformer_player.glb";

/// The shared data folder, whether or not it exists: `RIGCAST_SHARED_DATA` when set (a checkout
/// elsewhere than beside the data), else `../shared/data` beside the workspace.
pub fn shared_data_root() -> PathBuf {
    match std::env::var_os("RIGCAST_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    }
}

/// Path of a file in the shared test data, or `None` (with a printed reason) when absent.
pub fn shared_data(relative: &str) -> Option<PathBuf> {
    let p = shared_data_root().join(relative);
    if p.exists() {
        Some(p)
    } else {
        println!("SKIP: test data {} not found", p.display());
        None
    }
}

/// A clip of the shared test data, loaded, or `None` (with a printed reason) when absent.
pub fn shared_clip(relative: &str) -> Option<rigcast_retarget::Clip> {
    let path = shared_data(relative)?;
    Some(rigcast_sources::load_clip(&path).expect("a shared clip loads"))
}

/// Paths of several files in the shared test data, or `None` when any is absent (with a printed
/// reason for each one absent).
pub fn shared_data_all<const N: usize>(relative: [&str; N]) -> Option<[PathBuf; N]> {
    let found: Option<Vec<PathBuf>> = relative.map(shared_data).into_iter().collect();
    found?.try_into().ok()
}

/// The shared data folder when `probe` (a file in it) exists, or `None` with a printed reason
/// naming `what` the test needed.
pub fn shared_data_dir(probe: &str, what: &str) -> Option<PathBuf> {
    let p = shared_data_root();
    if p.join(probe).exists() {
        Some(p)
    } else {
        println!("SKIP: {what} not found ({})", p.join(probe).display());
        None
    }
}

/// Every label file of the shared data: `labels.json` at its root and `*/labels.json` in each
/// folder below it (later batches such as `zoo2/`), in a stable order. Keys in each are paths
/// relative to the root.
pub fn label_files(root: &std::path::Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(root)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path().join("labels.json"))
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    let top = root.join("labels.json");
    if top.is_file() {
        out.insert(0, top);
    }
    out
}

/// The labelled files of every label file ([`label_files`]) merged into one map: relative path
/// → its labels (`kind` and role → acceptable bone names). Keys starting with `_` (docs) are
/// left out; a file labelled twice keeps its first entry.
pub fn all_labels(root: &std::path::Path) -> serde_json::Map<String, serde_json::Value> {
    let mut out = serde_json::Map::new();
    for file in label_files(root) {
        let text =
            std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let value: serde_json::Value =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        for (key, v) in value.as_object().into_iter().flatten() {
            if !key.starts_with('_') && !out.contains_key(key) {
                out.insert(key.clone(), v.clone());
            }
        }
    }
    out
}
