//! The motion-graph walker's per-frame step (what the live fallback runs on the tick)
//! allocates nothing, counted with a global allocator over steps that take transitions,
//! blend, and take over from a held pose (checked, so the count is not of an idle walker).

mod alloc_count;
mod retarget_fixtures;

use std::f32::consts::TAU;
use std::sync::Arc;

use glam::{Quat, Vec3};
use retarget_fixtures::Humanoid;
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::graph::{GraphSettings, MotionGraph, Playback, Walker};
use rigcast_retarget::{Clip, Pose, Skeleton, WorldTransform};

use alloc_count::allocations;

fn gait(skel: &Skeleton, frames: usize) -> Vec<Pose> {
    let rest = skel.rest_pose();
    (0..frames)
        .map(|f| {
            let t = f as f32 / 50.0;
            let size = 0.5 + 0.08 * (TAU * t / 7.3).sin();
            let mut p = rest.clone();
            for b in skel.bone_ids().skip(1) {
                let k = b.0 as f32;
                let axis = Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), 0.4).normalize_or_zero();
                p.rotations[b.index()] = rest.rotations[b.index()]
                    * Quat::from_axis_angle(axis, size * (TAU * t + k).sin());
            }
            p.translations[0] += Vec3::Z * (1.2 * f as f32 / 60.0);
            p
        })
        .collect()
}

#[test]
fn walker_steps_allocate_nothing() {
    let skel = Arc::new(Humanoid::default().build());
    let clip = Clip::new("a", skel.clone(), gait(&skel, 400), 1.0 / 60.0).expect("clip");
    let g = MotionGraph::build(
        std::slice::from_ref(&clip),
        GraphSettings::default(),
        &mut |_| {},
    )
    .expect("builds");
    let analysis = analyze(&SkeletonView::from_clip(&skel, &clip.poses));
    let pb = Playback::new(&g, std::slice::from_ref(&clip), &analysis).expect("playback");
    let mut walker = Walker::new(&g, &pb, 5);
    let mut out = skel.rest_pose();
    let mut worlds = vec![WorldTransform::IDENTITY; skel.num_bones()];
    let held = clip.poses[77].clone();
    // Warm-up.
    walker.step(&pb, &mut out);
    let before = allocations();
    let mut blended = 0;
    for i in 0..2000 {
        if i == 1000 {
            walker.take_over(&pb, &held, 18, &mut worlds);
        }
        walker.step(&pb, &mut out);
        blended += usize::from(walker.is_blending());
    }
    let made = allocations() - before;
    assert!(
        walker.transitions_taken >= 3,
        "{}",
        walker.transitions_taken
    );
    assert!(blended > 50, "{blended}");
    assert_eq!(made, 0, "{made} allocations in 2000 steps");
}
