//! Every recording committed under `recordings/` (any depth) must read cleanly; those with
//! frames must also load as a clip and replay.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use rigcast_sources::recording::read_recording;
use rigcast_sources::{load_clip, Replay, ReplayOptions};

fn rcr_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rcr_files(&path, out);
        } else if path.extension().and_then(|e| e.to_str()) == Some("rcr") {
            out.push(path);
        }
    }
}

#[test]
fn every_committed_recording_reads_cleanly() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings");
    let mut files = Vec::new();
    rcr_files(&dir, &mut files);
    assert!(
        files.iter().any(|p| p.ends_with("demo.rcr")),
        "demo.rcr missing in {}",
        dir.display()
    );
    for path in files {
        let bytes = std::fs::read(&path).unwrap();
        let rec = read_recording(&bytes[..]).unwrap();
        assert!(rec.ended_cleanly, "{}: no end marker", path.display());
        assert!(rec.truncated_tail.is_none(), "{}", path.display());
        assert_eq!(rec.skipped_records, 0, "{}", path.display());
        if rec.frames.is_empty() {
            continue;
        }
        let clip = load_clip(&path).unwrap();
        let replay = Replay::new(clip, ReplayOptions::default()).unwrap();
        let mut pose = replay.skeleton().rest_pose();
        assert!(replay.sample(1.0, &mut pose).is_some());
    }
}
