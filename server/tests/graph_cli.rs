//! `rigcast graph build|info|walk` end to end on real clips in `../shared/data` (skipped with a
//! printed reason when absent): the real binary builds a graph of labelled human captures
//! (the first in sorted order that fit in about 1,600 frames at 120 Hz: a debug build of the
//! graph is the expensive part), `info` reports its size (the clips' frames at the first
//! clip's rate), `walk` writes a BVH whose frame count is the walk's and
//! whose root path has no jump, `walk --arrive-secs` one exactly that long (and refuses a time
//! shorter than the quickest walk, saying by how much), `walk --stay` wanders without a goal;
//! bad input gets a short error and a non-zero exit, not a panic.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rigcast_sources::load_clip;

#[path = "../../sources/tests/common/shared_data.rs"]
mod shared_data;
use shared_data::graph_clips;

/// `graph walk` on graph `g` from `from` to `to`, arriving after `arrive_secs`, into `out`.
fn walk_args<'a>(
    g: &'a str,
    (from, to): (&'a str, &'a str),
    arrive_secs: &'a str,
    out: &'a str,
) -> [&'a str; 11] {
    [
        "graph",
        "walk",
        g,
        "--from",
        from,
        "--to",
        to,
        "--arrive-secs",
        arrive_secs,
        "-o",
        out,
    ]
}

fn rigcast(args: &[&str], cache: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args(args)
        .env("XDG_CACHE_HOME", cache)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn build_info_and_walk_on_real_clips() {
    let found = graph_clips(1600);
    if found.len() < 2 {
        println!("SKIP: fewer than two labelled human clips for a graph");
        return;
    }
    let clips: Vec<PathBuf> = found.iter().map(|(l, _)| l.path.clone()).collect();
    // The graph's nodes: every clip's frames at the first clip's rate, counted here.
    let loaded: Vec<_> = clips.iter().map(|p| load_clip(p).unwrap()).collect();
    let nodes: usize = loaded
        .iter()
        .map(|c| c.resampled(loaded[0].frame_time_secs).unwrap().num_frames())
        .sum();
    // From a quarter into the second clip to three quarters into the longest other one.
    let name = |i: usize| clips[i].file_stem().unwrap().to_string_lossy().into_owned();
    let goal = (0..clips.len())
        .filter(|&i| i != 1)
        .max_by_key(|&i| loaded[i].num_frames())
        .unwrap();
    let (from, to) = (
        format!("{}:{}", name(1), loaded[1].num_frames() / 4),
        format!("{}:{}", name(goal), loaded[goal].num_frames() * 3 / 4),
    );
    let (from, to) = (from.as_str(), to.as_str());
    let stay_in = format!("{},{}", name(0), name(1));
    let dir = std::env::temp_dir().join(format!("rigcast-graph-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let graph = dir.join("g.rmg");
    let mut args: Vec<String> = vec!["graph".into(), "build".into()];
    args.extend(clips.iter().map(|p| p.display().to_string()));
    args.extend(["-o".into(), graph.display().to_string()]);
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = rigcast(&argv, &dir);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("100%"), "a progress bar: {}", text(&o));
    // Built again: from the cache.
    let o = rigcast(&argv, &dir);
    assert!(text(&o).contains("from the cache"), "{}", text(&o));

    let o = rigcast(&["graph", "info", graph.to_str().unwrap()], &dir);
    let info = text(&o);
    assert!(o.status.success(), "{info}");
    assert!(
        info.contains(&format!("nodes:        {nodes} frames")),
        "{info}"
    );

    let out = dir.join("walk.bvh");
    let o = rigcast(
        &[
            "graph",
            "walk",
            graph.to_str().unwrap(),
            "--from",
            from,
            "--to",
            to,
            "-o",
            out.to_str().unwrap(),
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", text(&o));
    let walk = load_clip(&out).unwrap();
    assert!(walk.num_frames() > 10);
    let root: Vec<_> = walk.poses.iter().map(|p| p.root_translation()).collect();
    for w in root.windows(3) {
        let jump = ((w[2] - w[1]) - (w[1] - w[0])).length();
        assert!(jump < 0.01, "root path jumps {jump} m");
    }

    // On time: the walk holds the start frame plus one frame per 1/120 s up to the arrival.
    let g = graph.to_str().unwrap();
    let timed = dir.join("timed.bvh");
    let o = rigcast(
        &walk_args(g, (from, to), "4", timed.to_str().unwrap()),
        &dir,
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("arrives at"), "{}", text(&o));
    let walk = load_clip(&timed).unwrap();
    let frames = (4.0 / walk.frame_time_secs).round() as usize;
    assert_eq!(walk.num_frames(), frames + 1, "{}", text(&o));
    // Wandering inside two clips, no goal.
    let stay = dir.join("stay.bvh");
    let o = rigcast(
        &["graph", "walk", g, "--from", from, "--stay", &stay_in]
            .iter()
            .chain(&["--wander", "2", "-o", stay.to_str().unwrap()])
            .copied()
            .collect::<Vec<_>>(),
        &dir,
    );
    assert!(o.status.success(), "{}", text(&o));
    let walk = load_clip(&stay).unwrap();
    let frames = (2.0 / walk.frame_time_secs).round() as usize;
    assert_eq!(
        walk.num_frames(),
        frames + 1,
        "the start and 2 s of wandering"
    );

    for (bad, says) in [
        (
            walk_args(g, (from, to), "0.05", "x.bvh").to_vec(),
            "the quickest takes",
        ),
        (
            vec![
                "graph", "walk", g, "--from", from, "--stay", "nobody", "--wander", "1", "-o",
                "x.bvh",
            ],
            "no clip is named",
        ),
        (
            vec!["graph", "walk", g, "--from", from, "-o", "x.bvh"],
            "nothing to walk to",
        ),
        (vec!["graph", "info", "/nonexistent.rmg"], "cannot read"),
        (
            vec!["graph", "info", clips[0].to_str().unwrap()],
            "not a valid motion graph",
        ),
        (
            vec![
                "graph",
                "walk",
                graph.to_str().unwrap(),
                "--from",
                "7:1",
                "--to",
                "0:1",
                "-o",
                "x.bvh",
            ],
            "does not exist",
        ),
        (
            vec![
                "graph",
                "walk",
                graph.to_str().unwrap(),
                "--from",
                "0:99999",
                "--to",
                "0:1",
                "-o",
                "x.bvh",
            ],
            "past its end",
        ),
    ] {
        let o = rigcast(&bad, &dir);
        assert!(!o.status.success());
        assert!(text(&o).contains(says), "{bad:?}: {}", text(&o));
        assert!(!text(&o).contains("panicked"));
    }
    let _ = std::fs::remove_dir_all(&dir);
}
