//! The two-performer checks on the pose2sim two-person demo (a woman in a grey shirt in front, a
//! shirtless man jumping behind her, a bystander at the back; 1088×1920, 60 fps, four cameras,
//! installed by `scripts/setup-vision.sh`), shared by `vision_multi_person` and
//! `vision_rounding` (included with `#[path]`; the including test declares `mod common` for
//! `vision_common.rs`).
//!
//! Identity is judged independently of the tracker: by the colour of each person's torso in
//! the decoded picture (grey cloth against bare skin). Each identity slot must keep the torso
//! colour it started with in every frame.
#![allow(clippy::unwrap_used)] // tests may unwrap
#![allow(dead_code)]

use crate::common::{assets_or_skip, cv, side_swaps, SEGMENTS};
use glam::{Vec2, Vec3};
use rigcast_sources::vision::landmarks::idx;
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, Landmarks, ModelKind, PipelineConfig, PosePipeline,
    RgbFrame,
};

/// Mean colour of the torso (a 3×5 grid around the spine, the middle third of the
/// shoulder–hip quad: a torso seen from the side is a thin sliver), from `frame`; landmarks
/// are in source pixels.
fn torso_colour(frame: &RgbFrame, lm: &Landmarks) -> Vec3 {
    let px = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y) / frame.source_from_frame;
    let (ls, rs, lh, rh) = (
        px(idx::LEFT_SHOULDER),
        px(idx::RIGHT_SHOULDER),
        px(idx::LEFT_HIP),
        px(idx::RIGHT_HIP),
    );
    let mut sum = Vec3::ZERO;
    for a in 0..3 {
        for b in 1..=5 {
            let (u, v) = (0.4 + 0.1 * a as f32, b as f32 / 6.0);
            let top = ls.lerp(rs, u);
            let bottom = lh.lerp(rh, u);
            let p = top.lerp(bottom, v);
            let c = frame.pixel(p.x as i32, p.y as i32);
            sum += Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        }
    }
    sum / 15.0
}

struct Person {
    frames: Vec<Option<Landmarks>>,
    colours: Vec<Option<Vec3>>,
}

/// Checks `cameras` with `model`, else the model `RIGCAST_TEST_MODEL` names (`full`, …), else
/// the default one.
pub fn check_cameras_with(test: &str, cameras: &[u32], model: Option<ModelKind>) {
    let Some(assets) = assets_or_skip(test) else {
        return;
    };
    let model = match (model, std::env::var("RIGCAST_TEST_MODEL")) {
        (Some(m), _) => m,
        (None, Ok(v)) => v.parse().unwrap(),
        (None, Err(_)) => PipelineConfig::default().model,
    };
    let config = PipelineConfig {
        assets: assets.clone(),
        model,
        ..PipelineConfig::default()
    };
    assert_eq!(
        config.tracker.max_people, 2,
        "the default tracks two people"
    );
    let mut failures = Vec::new();
    for &cam in cameras {
        let path = assets.pose2sim_multi_video(cam);
        let size = match std::env::var("RIGCAST_TEST_DECODE_SIDE") {
            Ok(v) => DecodeSize::ShortSide(v.parse().unwrap()),
            Err(_) => DecodeSize::FOR_MODEL,
        };
        let mut source = FfmpegSource::open_at(&path, size, 30.0).unwrap();
        let mut pipeline = PosePipeline::new(&config).unwrap();
        let mut frame = RgbFrame::default();
        let mut people: Vec<Person> = (0..2)
            .map(|_| Person {
                frames: Vec::new(),
                colours: Vec::new(),
            })
            .collect();
        while source.next_frame(&mut frame).unwrap() {
            pipeline.process_frame(&frame).unwrap();
            for (slot, person) in people.iter_mut().enumerate() {
                let lm = pipeline.person(slot).copied();
                let raw = pipeline.raw_person(slot);
                person.colours.push(raw.map(|lm| torso_colour(&frame, lm)));
                person.frames.push(lm);
            }
        }
        let num_frames = people[0].frames.len();
        let stats = pipeline.stats();
        let mut report = format!("cam{cam}: {num_frames} frames, {stats:?}");
        let mut swaps_seen = 0;
        // The median torso colour of each slot: who that slot is.
        let medians: Vec<Vec3> = people
            .iter()
            .map(|p| {
                let mut c: Vec<Vec3> = p.colours.iter().flatten().copied().collect();
                let mut m = Vec3::ZERO;
                for k in 0..3 {
                    c.sort_by(|a, b| a[k].total_cmp(&b[k]));
                    m[k] = c.get(c.len() / 2).map_or(0.0, |v| v[k]);
                }
                m
            })
            .collect();
        report += &format!(", torso colours {:.0} / {:.0}", medians[0], medians[1]);
        assert!(
            medians[0].distance(medians[1]) > 30.0,
            "{report}: the two slots hold the same person"
        );
        for (slot, person) in people.iter().enumerate() {
            let seen = person.frames.iter().flatten().count();
            let coverage = seen as f32 / num_frames as f32;
            report += &format!(", #{slot} in {:.1}%", coverage * 100.0);
            if coverage < 0.99 {
                failures.push(format!("cam{cam} #{slot} coverage {coverage:.3}"));
            }
            // A frame shows the other person when its colour is nearer the other's median than
            // its own slot's, and no farther from the other's than half the distance between
            // the two medians (the colour halfway between the two identities). A colour nearer
            // the other's median only by a little, and far from both, looks like neither: where
            // the man's torso grid takes in his dark shorts it lies about 90 from both medians
            // (camera 3, frames 89-92), and which median was nearer turned on a few units of
            // his median: the output's heatmap refinement (9e1c547) moved it by 6 and 4 such
            // frames were called hers, frame 92 among them with torso points the same to the
            // bit as without it (112/98/62, 97 from both medians). A slide onto her is still
            // caught: with the tracker's ON_OTHER_BODY at 0.22 his track shows her grey in frames
            // 87 and 90 (19 and 22 from her median, halfway 23; refined, frame 87 at 17 while
            // frame 90 sits at 23 from both).
            let (own, other) = (medians[slot], medians[1 - slot]);
            let halfway = own.distance(other) * 0.5;
            let nearer_other = |c: &&Vec3| c.distance(other) < c.distance(own);
            let swaps = person
                .colours
                .iter()
                .flatten()
                .filter(nearer_other)
                .filter(|c| c.distance(other) <= halfway)
                .count();
            let neither = person.colours.iter().flatten().filter(nearer_other).count() - swaps;
            report += &format!(
                " ({swaps} frames looking like the other, {neither} nearer the other's colour \
                 but like neither)"
            );
            if swaps + neither > 0 {
                let trace: Vec<String> = person
                    .colours
                    .iter()
                    .map(|c| c.map_or("-".into(), |c| format!("{:.0}/{:.0}/{:.0}", c.x, c.y, c.z)))
                    .collect();
                eprintln!("#{slot} torso colours per frame: {}", trace.join(" "));
            }
            if swaps > 0 {
                failures.push(format!(
                    "cam{cam} #{slot}: {swaps} frames show the other person"
                ));
            }
            let found: Vec<&Landmarks> = person.frames.iter().flatten().collect();
            for (name, a, b) in SEGMENTS {
                let lengths: Vec<f32> = found
                    .iter()
                    .map(|lm| lm.world[a].distance(lm.world[b]))
                    .collect();
                let c = cv(&lengths);
                report += &format!(", {name} cv {c:.3}");
                if c > 0.10 {
                    failures.push(format!("cam{cam} #{slot} {name} cv {c:.3}"));
                }
            }
            swaps_seen += side_swaps(&person.frames);
        }
        // Left and right change between two frames only where the tracker took the model's
        // labelling on the evidence of its readings, and that at most once a person: no
        // flicker, no swap unexplained.
        if swaps_seen as u64 > stats.relabels || stats.relabels > people.len() as u64 {
            failures.push(format!(
                "cam{cam}: sides swapped {swaps_seen} times, {} relabels",
                stats.relabels
            ));
        }
        eprintln!("{report}");
    }
    assert!(failures.is_empty(), "{failures:?}");
}
