//! The decoder's measuring perturbations (`RIGCAST_DECODE_NUDGE`, `RIGCAST_DECODE_EXACT_RGB`)
//! change the decoded picture as they say and by no more: the footage judge's runs under them
//! (BENCHMARKS.md, issue 32, the rounding spread) are only a measure of chance if each is a
//! small change of the same picture. One test (the variables are the process's), scaled to the
//! model's size and at the video's own size (the two filter paths).
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::path::Path;

use common::{assets_or_skip, mean_abs_diff};
use rigcast_sources::vision::{DecodeSize, FfmpegSource, FrameSource, RgbFrame};

fn first_frame(path: &Path, size: DecodeSize) -> RgbFrame {
    let mut source = FfmpegSource::open_at(path, size, 30.0).unwrap();
    let mut frame = RgbFrame::default();
    assert!(source.next_frame(&mut frame).unwrap());
    frame
}

fn nudged(path: &Path, size: DecodeSize, nudge: &str) -> RgbFrame {
    std::env::set_var("RIGCAST_DECODE_NUDGE", nudge);
    let frame = first_frame(path, size);
    std::env::remove_var("RIGCAST_DECODE_NUDGE");
    frame
}

#[test]
fn each_nudge_changes_the_decoded_picture_as_it_says() {
    let Some(assets) = assets_or_skip("decoder nudges") else {
        return;
    };
    let path = assets.pose2sim_video(1);
    for size in [DecodeSize::FOR_MODEL, DecodeSize::Full] {
        let plain = first_frame(&path, size);
        let (w, h) = (plain.width as usize, plain.height as usize);
        // One pixel to the left, the last column black.
        let shifted = nudged(&path, size, "shift");
        assert_eq!((shifted.width, shifted.height), (plain.width, plain.height));
        for y in 0..h {
            let row = |f: &RgbFrame| f.data[y * w * 3..(y + 1) * w * 3].to_vec();
            let (p, s) = (row(&plain), row(&shifted));
            assert_eq!(s[..(w - 1) * 3], p[3..], "{size:?} row {y}");
            assert_eq!(s[(w - 1) * 3..], [0, 0, 0], "{size:?} row {y}");
        }
        // One level brighter, 255 kept.
        let brighter = nudged(&path, size, "level");
        for (b, p) in brighter.data.iter().zip(&plain.data) {
            assert_eq!(*b, p.saturating_add(1), "{size:?}");
        }
        // Without the loop filter, and with the exact RGB conversion: other values, a few
        // levels apart on average.
        let unfiltered = nudged(&path, size, "deblock");
        std::env::set_var("RIGCAST_DECODE_EXACT_RGB", "1");
        let exact = first_frame(&path, size);
        std::env::remove_var("RIGCAST_DECODE_EXACT_RGB");
        for (what, frame) in [("deblock", &unfiltered), ("exact", &exact)] {
            let d = mean_abs_diff(frame, &plain);
            eprintln!("{size:?} {what}: mean {d:.3} levels from the plain decode");
            assert!(d > 0.0 && d < 3.0, "{size:?} {what}: {d}");
        }
        // An unknown name changes nothing.
        assert_eq!(nudged(&path, size, "none").data, plain.data, "{size:?}");
    }
}
