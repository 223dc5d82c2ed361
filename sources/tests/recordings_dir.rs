//! Every recording committed in `recordings/` must read cleanly and replay.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use rigcast_sources::recording::read_recording;
use rigcast_sources::{load_clip, Replay, ReplayOptions};

#[test]
fn every_committed_recording_reads_cleanly() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("rcr") {
            continue;
        }
        let bytes = std::fs::read(&path).unwrap();
        let rec = read_recording(&bytes[..]).unwrap();
        assert!(rec.ended_cleanly, "{}: no end marker", path.display());
        assert!(rec.truncated_tail.is_none(), "{}", path.display());
        assert_eq!(rec.skipped_records, 0, "{}", path.display());
        let clip = load_clip(&path).unwrap();
        let replay = Replay::new(clip, ReplayOptions::default()).unwrap();
        let mut pose = replay.skeleton().rest_pose();
        assert!(replay.sample(1.0, &mut pose).is_some());
        count += 1;
    }
    assert!(count >= 1, "no recordings found in {}", dir.display());
}
