//! `--source webcam:INDEX` in a build without the `webcam` feature (the default build): the
//! real binary refuses with an error that says how to rebuild, instead of failing obscurely.
#![allow(clippy::unwrap_used)]

mod common;

#[cfg(not(feature = "webcam"))]
#[test]
fn webcam_without_the_feature_says_how_to_rebuild() {
    use std::process::Command;
    let out = Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args([
            "serve",
            "--listen",
            "127.0.0.1:0",
            "--no-mapping-cache",
            "--source",
            "webcam:0",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "served without webcam support: {err}"
    );
    assert!(
        err.contains("webcam:0")
            && err.contains("--features webcam")
            && err.contains("libclang-dev"),
        "{err}"
    );
    // A config file names the same source kind and gets the same answer.
    let cfg = common::test_file(
        "webcam",
        "rigcast.toml",
        "listen = \"127.0.0.1:0\"\nmapping_cache = false\n[[sources]]\nkind = \"webcam\"\nindex = 3\n",
    );
    let out = Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args(["serve", "--config", cfg.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("webcam:3") && err.contains("--features webcam"),
        "{err}"
    );
    // A malformed index is a usage error naming the expected form.
    let out = Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args([
            "serve",
            "--listen",
            "127.0.0.1:0",
            "--source",
            "webcam:front",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("webcam:INDEX"), "{err}");
    let _ = std::fs::remove_dir_all(cfg.parent().unwrap());
}
