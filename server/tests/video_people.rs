//! Bad `#PERSON` subjects of a video are refused at start with a short error, by the real
//! binary: a person that is not a number, a person beyond the people tracked, and two entries
//! of one file that disagree on how many people to track.
#![allow(clippy::unwrap_used)]

mod common;

use rigcast_sources::vision::VisionAssets;

fn serve_fails(args: &[&str]) -> String {
    let mut all = vec!["serve", "--listen", "127.0.0.1:0", "--no-mapping-cache"];
    all.extend_from_slice(args);
    common::rigcast_fails(all)
}

#[test]
fn a_person_that_is_not_a_number_is_a_grammar_error() {
    let err = serve_fails(&["--source", "video:clip.mp4#front"]);
    assert!(err.contains("video:FILE#PERSON"), "{err}");
    let err = serve_fails(&["--source", "webcam:0#-1"]);
    assert!(err.contains("webcam:INDEX#PERSON"), "{err}");
}

#[test]
fn persons_beyond_the_people_tracked_and_disagreeing_counts_are_refused() {
    let assets = VisionAssets::from_env();
    let video = assets.pose2sim_multi_video(2);
    if !assets.is_ready() || !video.is_file() {
        eprintln!("SKIP: vision models or footage not installed (scripts/setup-vision.sh)");
        return;
    }
    let arg = format!("video:{}#2", video.display());
    let err = serve_fails(&["--source", &arg]);
    assert!(
        err.contains("no person #2") && err.contains("people = 3"),
        "{err}"
    );
    assert!(err.contains("only 2 people are tracked (#0..#1)"), "{err}");

    let dir = std::env::temp_dir().join(format!("rigcast-video-people-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("rigcast.toml");
    let path = video.display();
    std::fs::write(
        &cfg,
        format!(
            "[[sources]]\nkind = \"video\"\npath = \"{path}\"\npeople = 3\n\
             [[sources]]\nkind = \"video\"\npath = \"{path}\"\nperson = 1\npeople = 2\n"
        ),
    )
    .unwrap();
    let err = serve_fails(&["--config", cfg.to_str().unwrap()]);
    assert!(
        err.contains("people = 2 here") && err.contains("tracks 3"),
        "{err}"
    );
}
