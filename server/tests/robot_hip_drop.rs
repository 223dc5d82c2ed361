//! The foot lock on the Godot platformer robot (short legs, 0.62 m; CMU 131_01 retargeted
//! offline): with the lock its thighs point up to 62° away from the unlocked retarget's (48.4°
//! with the lock of a9a275d, 35.7° since a swinging foot lifted onto its floor also moves over
//! the ground where its leg turns least, `lift_aside`; the worst frame is still the kneel's
//! pinned ankle lifted 14.3 cm out of the floor). Was it the hips coming down to reach pinned feet? Measured per hip-drop
//! limit (`LockSettings::max_drop_ratio` 0.3 … 0) and per drift release (`max_drift_ratio`): the
//! largest angle between a thigh's direction with and without the lock, where it happens, the
//! hips' largest drop and the planted feet's drift. Finding: no limit changes the 62° — the
//! worst frames are the lock lifting an ankle about 15 cm out of the floor, into which the
//! plain retarget sinks the robot's feet (BENCHMARKS.md: 15.7 cm below the floor unlocked),
//! so the knee bends to keep the foot on the floor; a lower hip-drop limit only costs drift.
//! The fix belongs to the robot's root height in the retarget, not to the lock.
//!
//! Where the plain retarget sinks the robot's feet: only while the performer goes down on one
//! knee (frames 340-440 of 994, its hips at 47-77 % of their standing height; the robot's hips
//! 0.25-0.47 m against 0.60 standing). Elsewhere its lowest foot stays within 3.9 cm of the
//! floor. The cause is the legs' proportions: the robot's thigh is 0.19 m over a 0.43 m shin
//! (0.45), the performer's 0.41 over 0.39 (1.05). The root's height is the performer's,
//! scaled by the whole legs' ratio (0.78): with the knees bent 90-120° the same directions put
//! the robot's standing ankle 10 cm below the scaled performer's (it hangs from a long, nearly
//! upright shin) and its kneeling leg's ankle 17 cm above (a short thigh holds the knee up):
//! no root height stands both feet where the performer's stand. Placing the root every frame
//! so the lowest foot stands (`FootContact::EveryFrame`) was tried: issue 35's pairs within
//! thigh and shin 123 -> 113 of 152, floor 150 -> 142 (the robot's own pairs a little better:
//! CMU run 2.9/11.0 -> 1.3/5.6°); not taken. Counting a landing foot's gap to its pin in the
//! lock's pelvis height beside the standing feet' (weighted as it comes down): 123 -> 117, the
//! robot's CMU 131_01 thigh 5.8/22.9 -> 6.4/24.0°; not taken.
//!
//! A study of these two files (the figures above were read from them), so it names them and
//! skips when either is absent.
#![allow(clippy::unwrap_used)]

mod common;

use rigcast_retarget::footplant::{detect_clip, find_legs, FootLock, LockSettings, PlantSettings};
use rigcast_retarget::{world_transforms, Mapping, RootMotion};
use rigcast_server::offline::plan_mapping;

#[test]
fn robot_thigh_directions_per_hip_drop_limit() {
    let files = [
        common::CMU_WALK,
        "zoo/gltf/godot_robot__platformer_player.glb",
    ];
    let Some([walk, robot]) = common::shared_data_all(files) else {
        return;
    };
    let source = rigcast_sources::load_clip(&walk).unwrap();
    let target = rigcast_sources::load_rig(&robot).unwrap().0;
    let plan = plan_mapping(&source, &target, None).unwrap();
    let opts = plan.retarget_options(&source, RootMotion::default());
    let dt = source.frame_time_secs as f32;
    for (limit, drift_ratio) in [
        (0.3f32, 0.35f32),
        (0.1, 0.35),
        (0.0, 0.35),
        (0.3, 0.2),
        (0.3, 0.12),
    ] {
        let mut mapping =
            Mapping::build(&[&source.skeleton], &target.skeleton, &plan.table, &opts).unwrap();
        if let Some(floor) = mapping.measure_source_floor(&source.poses) {
            mapping.set_source_floor_y(floor);
        }
        let settings = LockSettings {
            max_drop_ratio: limit,
            max_drift_ratio: drift_ratio,
            ..LockSettings::default()
        };
        let mut lock = FootLock::new(
            &mapping,
            &plan.source_analysis,
            &plan.target_analysis,
            settings,
        )
        .unwrap();
        let plants = detect_clip(
            &source.skeleton,
            lock.source_legs(),
            &source.poses,
            dt,
            plan.source_up,
            &PlantSettings::default(),
        );
        let legs = find_legs(&target.skeleton, &plan.target_analysis);
        let root = mapping.root_bone().unwrap().index();
        let (mut worst, mut drop, mut drift, mut n) = (0.0f32, 0.0f32, 0.0f64, 0usize);
        let mut at = (0usize, 0usize, 0.0f32, false);
        let mut over30 = 0usize;
        let mut out = mapping.new_target_pose();
        let mut last: Option<Vec<glam::Vec3>> = None;
        for (i, p) in source.poses.iter().enumerate() {
            mapping.apply_one(p, &mut out).unwrap();
            let free = world_transforms(&target.skeleton, &out);
            lock.apply_planted(plants.frame(i), dt, &mut out);
            let held = world_transforms(&target.skeleton, &out);
            drop = drop.max(free[root].translation.y - held[root].translation.y);
            let feet: Vec<glam::Vec3> = legs
                .iter()
                .map(|l| held[l.foot.index()].translation)
                .collect();
            for (li, l) in legs.iter().enumerate() {
                let d = |w: &[rigcast_retarget::WorldTransform]| {
                    w[l.lower.index()].translation - w[l.upper.index()].translation
                };
                let a = d(&free).angle_between(d(&held)).to_degrees();
                if a > 30.0 {
                    over30 += 1;
                }
                if a > worst {
                    worst = a;
                    let moved =
                        (held[l.foot.index()].translation - free[l.foot.index()].translation).y;
                    at = (i, li, moved, lock.is_locked(li));
                }
            }
            if let Some(prev) = &last {
                for k in 0..lock.source_legs().len() {
                    if i > 0
                        && plants.is_planted(i, k)
                        && plants.is_planted(i - 1, k)
                        && k < feet.len()
                    {
                        let m = feet[k] - prev[k];
                        drift += f64::from(glam::Vec3::new(m.x, 0.0, m.z).length()) * 100.0;
                        n += 1;
                    }
                }
            }
            last = Some(feet);
        }
        let drift = drift / n.max(1) as f64;
        println!("  worst at frame {} leg {}: ankle raised {:.1} cm by the lock, locked {}; {over30} leg-frames over 30 deg of {}", at.0, at.1, at.2 * 100.0, at.3, 2 * source.num_frames());
        println!("max_drop_ratio {limit}, max_drift_ratio {drift_ratio}: thigh off the free retarget by up to {worst:.1} deg, hips down up to {:.1} cm, planted-foot drift {drift:.4} cm/frame", drop * 100.0);
        assert!(
            worst > 30.0,
            "the thighs now follow the free retarget: {worst:.1} deg"
        );
        assert!(
            at.2 > 0.10,
            "the worst thigh is not a foot lifted out of the floor: {:.3} m",
            at.2
        );
        assert!(drift < 0.05, "{drift}");
    }
}
