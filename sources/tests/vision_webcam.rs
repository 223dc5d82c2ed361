//! Opening a webcam on a machine without one (CI, this build box) is a clear
//! [`VisionError::Webcam`] naming the cameras that exist, never a panic. (The capture path
//! itself runs against an emulated V4L2 camera in `server/tests/webcam_emulated.rs`.)
#![allow(clippy::unwrap_used)] // tests may unwrap

use rigcast_sources::vision::{open_webcam, VisionError};

/// True when this machine has a V4L2 device node, in which case opening may succeed and
/// the "no camera" expectations do not apply.
#[cfg(feature = "webcam")]
fn has_video_device() -> bool {
    std::fs::read_dir("/dev")
        .map(|d| {
            d.flatten()
                .any(|e| e.file_name().to_string_lossy().starts_with("video"))
        })
        .unwrap_or(false)
}

#[cfg(feature = "webcam")]
#[test]
fn opening_a_missing_webcam_is_a_clear_error() {
    if has_video_device() {
        eprintln!("SKIP opening_a_missing_webcam_is_a_clear_error: /dev/video* present");
        return;
    }
    assert!(rigcast_sources::vision::list_cameras().is_empty());
    for index in [0u32, 7] {
        let result = std::panic::catch_unwind(|| {
            rigcast_sources::vision::Webcam::open(index, Default::default())
        });
        let err = match result {
            Ok(Ok(cam)) => panic!("camera {index} opened without a device: {cam:?}"),
            Ok(Err(e)) => e,
            Err(_) => panic!("Webcam::open({index}) panicked"),
        };
        assert!(matches!(err, VisionError::Webcam(_)), "{err:?}");
        let msg = err.to_string();
        eprintln!("camera {index}: {msg}");
        assert!(msg.starts_with("webcam: "), "{msg}");
        assert!(
            msg.contains(&format!("no camera {index}")) && msg.contains("cameras here are: none"),
            "message names neither the missing camera nor what exists: {msg}"
        );
        // The boxed entry point used by the server behaves the same.
        let err = open_webcam(index, Default::default()).err().unwrap();
        assert!(matches!(err, VisionError::Webcam(_)), "{err:?}");
    }
}

#[cfg(not(feature = "webcam"))]
#[test]
fn without_the_feature_open_webcam_says_how_to_get_it() {
    let err = open_webcam(0, Default::default()).err().unwrap();
    assert!(matches!(err, VisionError::Webcam(_)), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("--no-default-features"), "{msg}");
    assert!(msg.contains("libclang-dev"), "{msg}");
}
