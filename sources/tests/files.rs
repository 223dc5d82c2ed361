//! File-level API: dispatch on extension, save → load round trips, errors naming the file.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use rigcast_sources::{describe, embedded_demo, load_clip, load_clip_with, save_clip};
use rigcast_sources::{LoadOptions, SourceError};

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rigcast-sources-{tag}-{}", std::process::id()));
    // A folder left by an earlier process with the same id is stale.
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn save_and_load_every_writable_format() {
    let demo = embedded_demo().unwrap();
    let dir = temp_dir("formats");
    for ext in ["bvh", "glb", "rcr"] {
        let path = dir.join(format!("demo.{ext}"));
        save_clip(&path, &demo).unwrap();
        let opts = LoadOptions {
            bvh_scale: Some(0.01),
            ..Default::default()
        };
        let back = load_clip_with(&path, &opts).unwrap();
        assert_eq!(back.skeleton.num_bones(), 25, "{ext}");
        assert_eq!(back.num_frames(), demo.num_frames(), "{ext}");
        assert!((back.fps() - 60.0).abs() < 1e-3, "{ext}: {}", back.fps());
        let info = describe(&path).unwrap();
        assert!(
            (1.6..1.9).contains(&info.height_m),
            "{ext}: {}",
            info.height_m
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn errors_name_the_file() {
    let dir = temp_dir("errors");
    let bad = dir.join("broken.bvh");
    std::fs::write(&bad, "HIERARCHY\nROOT a\n{\n OFFSET 0 zero 0\n").unwrap();
    let e = load_clip(&bad).err().unwrap();
    let msg = e.to_string();
    assert!(
        msg.contains("broken.bvh") && msg.contains("line 4"),
        "{msg}"
    );
    assert!(matches!(e.root(), SourceError::BadNumber { line: 4, .. }));
    let e = load_clip(&dir.join("missing.bvh")).err().unwrap();
    assert!(matches!(e, SourceError::Io { .. }), "{e}");
    let e = load_clip(&dir.join("x.fbx")).err().unwrap();
    assert!(
        matches!(e.root(), SourceError::UnsupportedExtension { .. }),
        "{e}"
    );
    let e = save_clip(&dir.join("x.gltf"), &embedded_demo().unwrap())
        .err()
        .unwrap();
    assert!(
        matches!(e.root(), SourceError::UnsupportedExtension { .. }),
        "{e}"
    );
    // A recording with the wrong magic, named as such.
    let fake = dir.join("fake.rcr");
    std::fs::write(&fake, b"not a recording at all").unwrap();
    let e = load_clip(&fake).err().unwrap();
    assert!(matches!(e.root(), SourceError::BadMagic { .. }), "{e}");
    assert!(e.to_string().contains("fake.rcr"));
    std::fs::remove_dir_all(&dir).ok();
}
