//! `--source webcam:INDEX` through the real binary on a machine without a camera (CI, this
//! build box): the default build accepts the source and refuses to start with an error naming
//! the cameras that exist; a build without the `webcam` feature says how to get it.
//! (A real camera path is exercised against the emulated V4L2 device in `webcam_emulated.rs`.)
#![allow(clippy::unwrap_used)]

mod common;

use std::process::Command;

fn serve(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .arg("serve")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// True when this machine has a /dev/video* node (then "no camera" cannot be checked).
fn has_video_device() -> bool {
    std::fs::read_dir("/dev")
        .map(|d| {
            d.flatten()
                .any(|e| e.file_name().to_string_lossy().starts_with("video"))
        })
        .unwrap_or(false)
}

#[test]
fn webcam_without_a_camera_is_a_clear_error_naming_the_cameras() {
    if cfg!(feature = "webcam") && has_video_device() {
        eprintln!("SKIP: /dev/video* present, a camera may open");
        return;
    }
    let expect = |err: &str, source: &str| {
        assert!(err.contains(source), "{err}");
        if cfg!(feature = "webcam") {
            assert!(err.contains("the cameras here are: none"), "{err}");
        } else {
            assert!(
                err.contains("--no-default-features") && err.contains("libclang"),
                "{err}"
            );
        }
    };
    let common = ["--listen", "127.0.0.1:0", "--no-mapping-cache"];
    let (ok, err) = serve(&[&common[..], &["--source", "webcam:0"]].concat());
    assert!(!ok, "served without a camera: {err}");
    expect(&err, "webcam");
    // Options parse (the mode is chosen only once a camera is there).
    let (ok, err) = serve(&[&common[..], &["--source", "webcam:0?width=1280&fps=60"]].concat());
    assert!(!ok);
    expect(&err, "webcam");
    // A config file names the same source kind and gets the same answer.
    let cfg = common::test_file(
        "webcam",
        "rigcast.toml",
        "listen = \"127.0.0.1:0\"\nmapping_cache = false\n[[sources]]\nkind = \"webcam\"\nindex = 3\nfps = 30\n",
    );
    let (ok, err) = serve(&["--config", cfg.to_str().unwrap()]);
    assert!(!ok);
    expect(&err, "webcam");
    let _ = std::fs::remove_dir_all(cfg.parent().unwrap());
}

#[test]
fn malformed_webcam_arguments_name_the_expected_form() {
    for bad in [
        "webcam:front",
        "webcam:0?zoom=2",
        "webcam:0?width=0",
        "webcam:0?format=h264",
    ] {
        let (ok, err) = serve(&["--listen", "127.0.0.1:0", "--source", bad]);
        assert!(!ok, "{bad} accepted");
        assert!(err.contains("webcam:INDEX"), "{bad}: {err}");
    }
}
