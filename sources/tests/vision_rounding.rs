//! Each frame's reading must not hinge on the decoder's rounding. ffmpeg's exact RGB conversion
//! (`RIGCAST_DECODE_EXACT_RGB`) differs from its default by 1-4 levels a channel; the landmarks
//! move by up to a few percent of the torso, each next crop with them, and on a close, occluded
//! or blurred crop the landmark model's presence swings across the tracker's keep cut as the
//! crop moves a pixel. A tracker that keeps or loses a person on one such reading tracks the
//! two performers of `vision_multi_person` under one conversion and loses one of them under
//! the other; these are that test's bounds, decoded the exact way (every test of this binary
//! sets the variable before its decoder starts, so they agree on it).
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;
#[path = "common/two_person.rs"]
mod two_person;

use rigcast_sources::vision::ModelKind;
use two_person::check_cameras_with;

fn exact_rgb() {
    std::env::set_var("RIGCAST_DECODE_EXACT_RGB", "1");
}

/// Ignored until it passes (BENCHMARKS.md, issue 32, "the rounding spread"): f872176 fails
/// with camera 2's man in 93 % of the frames and camera 3's in one frame on the woman; with
/// the standing-height continuity (`Track::continued_by`) camera 2's man is in 98 %, found
/// at frame 3 instead of 1 (the detector's first pass scores him under its cut under this
/// conversion), and camera 3 is as before.
#[test]
#[ignore = "fails today: the tracker's decisions still hinge on the rounding"]
fn two_performers_keep_their_identities_under_the_exact_rgb_conversion() {
    exact_rgb();
    check_cameras_with(
        "two-person, exact RGB",
        &[1, 2, 3, 4],
        Some(ModelKind::Lite),
    );
}

/// Ignored until it passes: camera 2's man in 98 % and camera 3's in 96 % of the frames, on
/// f872176 and with the standing-height continuity alike.
#[test]
#[ignore = "fails today: the tracker's decisions still hinge on the rounding"]
fn two_performers_with_the_full_model_under_the_exact_rgb_conversion() {
    exact_rgb();
    check_cameras_with(
        "two-person, full model, exact RGB",
        &[1, 2, 3, 4],
        Some(ModelKind::Full),
    );
}
