//! The foot lock and a live graft on a simulated clock, with no socket and no real time: the
//! engine ([`Engine`]) runs a performer whose source the test feeds frame by frame
//! ([`Input::Frame`]) and is given each tick's time ([`Input::Timeout`]); what it yields is
//! kept, the planted feet reported as typed events by its own foot-plant checks.
//!
//! - Foot lock (the first labelled walk of the shared data, found by its motion, on the mannequin, mapped as the server's
//!   mapper does): both feet plant and lift in turn; once a plant has settled (the lock eases a landing foot onto its
//!   pin over about 0.2 s) the joint the planted foot stands on (its foot or toe joint, the
//!   lower) moves no more than 0.5 mm per tick, while lifted
//!   feet travel; every `footplants` event names the frame it describes and gives each foot's
//!   position as forward kinematics of that frame and its flag as the tick stored it.
//! - Graft (the same walk: an upper source and the walk looping one stride
//!   at a time below the waist): the character travels, its hips never jump between ticks
//!   (across the stride's seam too), the elbow follows the upper source; the upper source is lost and the
//!   character eases to rest on the spot, then blends back once it returns.
//!
//! Both skip, saying so, when the shared data is absent.
#![allow(clippy::unwrap_used)]

mod common;

use std::sync::Arc;
use std::time::Duration;

use rigcast_engine::clock::TickTime;
use rigcast_engine::events::Event;
use rigcast_engine::graft_live::LiveGraft;
use rigcast_engine::performer::BuiltMapping;
use rigcast_engine::settings::OnLost;
use rigcast_engine::subject::Subject;
use rigcast_engine::{Engine, Input};
use rigcast_protocol::{SourceState, TargetMotion};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings};
use rigcast_retarget::mapping::{auto_map, MapOptions};
use rigcast_retarget::{
    world_transforms, Clip, Mapping, Pose, RetargetOptions, RootMotion, Skeleton,
};
use rigcast_server::offline::plan_mapping;

/// 60 Hz, in whole nanoseconds.
const TICK: Duration = Duration::from_nanos(16_666_667);
/// Ticks a landing foot takes to settle onto its pin (0.2 s).
const SETTLE_TICKS: usize = 12;

/// `clip`'s skeleton mapped onto `target` (analysed from its motion), with `root_motion`.
fn map(clip: &Clip, target: &Skeleton, root_motion: RootMotion) -> Mapping {
    let table = auto_map(
        &SkeletonView::from_clip(&clip.skeleton, &clip.poses),
        &SkeletonView::rest(target),
        &MapOptions::default(),
    );
    let options = RetargetOptions {
        root_motion,
        ..RetargetOptions::default()
    };
    Mapping::build(&[&clip.skeleton], target, &table, &options).unwrap()
}

/// A source subject and a target performer on the engine, which holds the source's slot.
struct Rig {
    engine: Engine,
    target: Arc<Subject>,
    now: TickTime,
}

impl Rig {
    fn new(clip: &Clip, skeleton: &Arc<Skeleton>, built: BuiltMapping) -> Rig {
        let (source, source_tx) = Subject::new(0, "performer".into(), clip.skeleton.clone());
        let source = Arc::new(source);
        let (target, performer) =
            common::performer(1, skeleton, std::slice::from_ref(&source), OnLost::Ease);
        // The feet the lock holds, named as the mapper names them when it hands a mapping over.
        *target.stats.locked_feet.lock().unwrap() = (built.foot_lock.iter())
            .flat_map(|l| l.target_legs())
            .map(|leg| skeleton.name(leg.foot).to_string())
            .collect();
        let now = TickTime::now();
        let mut engine = common::engine(
            vec![source.clone(), target.clone()],
            Vec::new(),
            vec![performer],
            1.0 / TICK.as_secs_f64(),
            now.instant,
        );
        engine.feed(0, source_tx, false);
        // Handed over as the mapper hands a built mapping over.
        engine.handle_input(Input::Mapping { target: 1, built });
        Rig {
            engine,
            target,
            now,
        }
    }

    /// The source's health changes.
    fn source_state(&mut self, state: SourceState) {
        (self.engine).handle_input(Input::Health { subject: 0, state });
    }

    /// One tick 1/60 s after the last, after the source sends `pose` (when given); the events
    /// the engine yielded.
    fn tick(&mut self, pose: Option<&Pose>) -> Vec<Event> {
        self.now = self.now.after(TICK);
        if let Some(pose) = pose {
            self.engine.handle_input(Input::Frame {
                subject: 0,
                time: self.now,
                capture_nanos: self.now.unix_nanos,
                seq: 0,
                pose,
            });
        }
        let (out, next) = common::engine_at(&mut self.engine, self.now);
        assert_eq!(out.frames.len(), 2, "both subjects' frames every tick");
        assert_eq!(out.ticked, [self.now], "one tick, at the time given");
        assert!(next <= self.now.after(TICK).instant, "the next tick is due");
        out.events
    }

    fn shown(&self) -> Pose {
        self.target.latest.borrow().pose.clone()
    }
}

/// `clip`'s pose at `secs`, looping (nearest frame).
fn pose_at(clip: &Clip, secs: f64) -> &Pose {
    let k = (secs / clip.frame_time_secs).round() as usize;
    &clip.poses[k % clip.poses.len()]
}

/// World position of bone `name` in `pose`.
fn at(skel: &Skeleton, pose: &Pose, name: &str) -> glam::Vec3 {
    world_transforms(skel, pose)[skel.bone(name).unwrap().index()].translation
}

#[test]
fn planted_feet_hold_still_on_a_simulated_clock() {
    let wall = std::time::Instant::now();
    // A walk that travels (the bundled demo walks on the spot: its feet never stand still):
    // the first labelled walk, found by its motion (a whole walk is slow in debug: one).
    let Some((_, walk, _)) = common::first_walk() else {
        return;
    };
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    // Mapped and locked as the server's mapper does it: the offline plan's options at the
    // tick's frame time, the source's floor measured on its clip.
    let character = Clip::new("mannequin", target.clone(), Vec::new(), 1.0 / 30.0).unwrap();
    let plan = plan_mapping(&walk, &character, None).unwrap();
    let options = RetargetOptions {
        frame_time_secs: TICK.as_secs_f32(),
        ..plan.retarget_options(&walk, RootMotion::default())
    };
    let mut mapping = Mapping::build(&[&walk.skeleton], &target, &plan.table, &options).unwrap();
    if let Some(floor) = mapping.measure_source_floor(&walk.poses) {
        mapping.set_source_floor_y(floor);
    }
    let (sa, ta) = (&plan.source_analysis, &plan.target_analysis);
    let lock = FootLock::new(&mapping, sa, ta, LockSettings::default()).expect("a foot lock");
    let feet: Vec<String> = (lock.target_legs())
        .map(|l| target.name(l.foot).to_string())
        .collect();
    // Each foot's leg (thigh and shin at rest), the unit of the reports' allowance.
    let legs: Vec<f32> = (lock.target_legs())
        .map(|l| {
            let offset =
                |b: rigcast_retarget::BoneId| target.rest()[b.index()].translation.length();
            offset(l.foot) + target.parent(l.foot).map_or(0.0, offset)
        })
        .collect();
    // Each foot's joints it may stand on: its foot joint, and its toes where it has them.
    let contacts: Vec<Vec<String>> = (lock.target_legs())
        .map(|l| {
            [Some(l.foot), l.toes]
                .into_iter()
                .flatten()
                .map(|b| target.name(b).to_string())
                .collect()
        })
        .collect();
    let mut rig = Rig::new(
        &walk,
        &target,
        BuiltMapping {
            mapping,
            foot_lock: Some(lock),
            graft: None,
        },
    );
    // Four seconds of the walk at its own rate, on the 60 Hz tick.
    let ticks = 240;
    let mut shown: Vec<(Pose, u32)> = Vec::new();
    let mut events = 0;
    // The latest report's planted feet (index, position), and how far a planted foot has been
    // from it at most beyond what the checks allow.
    let mut reported: Vec<(usize, glam::Vec3)> = Vec::new();
    let (mut worst_stale, mut farthest) = (f32::NEG_INFINITY, 0.0f32);
    for k in 0..ticks {
        let secs = k as f64 * TICK.as_secs_f64();
        for event in rig.tick(Some(pose_at(&walk, secs))) {
            let Event::Footplants(report) = event else {
                continue;
            };
            events += 1;
            reported = (report.feet.iter().enumerate())
                .filter(|(_, f)| f.planted)
                .map(|(i, f)| (i, glam::Vec3::from(f.position)))
                .collect();
            // The report describes the frame the tick just published, with the tick's flags.
            let frame = rig.target.latest.borrow();
            assert_eq!(report.seq, frame.seq);
            let bits = rig
                .target
                .stats
                .feet_locked
                .load(std::sync::atomic::Ordering::Relaxed);
            for (i, foot) in report.feet.iter().enumerate() {
                assert_eq!(foot.bone, feet[i]);
                assert_eq!(foot.planted, bits & (1 << i) != 0, "{}", foot.bone);
                let fk = at(&target, &frame.pose, &foot.bone);
                let off = (fk - glam::Vec3::from(foot.position)).length();
                assert!(off < 1e-5, "{}: {off} m off FK of its frame", foot.bone);
            }
        }
        let bits = rig
            .target
            .stats
            .feet_locked
            .load(std::sync::atomic::Ordering::Relaxed);
        shown.push((rig.shown(), bits));
        // A planted foot is re-reported once it moves 2 % of its leg from its report, checked
        // every other tick (30 Hz): it may be that far plus its move since the last check.
        for &(i, position) in &reported {
            let now = at(&target, &shown[k].0, &feet[i]);
            let recent = k
                .checked_sub(2)
                .map_or(0.0, |j| now.distance(at(&target, &shown[j].0, &feet[i])));
            let allowed = rigcast_engine::footplants::MOVED_SHARE_OF_LEG * legs[i] + recent;
            worst_stale = worst_stale.max(now.distance(position) - allowed);
            farthest = farthest.max(now.distance(position));
        }
    }
    println!(
        "a planted foot stood up to {farthest:.4} m from its report, {:.4} m within the allowance",
        -worst_stale
    );
    assert!(
        worst_stale <= 1e-4,
        "a planted foot stood {worst_stale} m farther from its report than the checks allow"
    );
    let mut judged = 0;
    for (i, foot) in feet.iter().enumerate() {
        let planted = |k: usize| shown[k].1 & (1 << i) != 0;
        assert!((0..ticks).any(planted), "{foot} never planted");
        assert!((0..ticks).any(|k| !planted(k)), "{foot} never lifted");
        let mut worst_drift = 0.0f32;
        let mut lifted_travel = 0.0f32;
        let mut k = 0;
        while k < ticks {
            let start = k;
            let state = planted(k);
            while k < ticks && planted(k) == state {
                k += 1;
            }
            let span: Vec<glam::Vec3> =
                (start..k).map(|j| at(&target, &shown[j].0, foot)).collect();
            if state && span.len() > SETTLE_TICKS + 2 {
                judged += 1;
                for j in start + SETTLE_TICKS + 1..k {
                    // The joint the foot stands on: the lowest on the tick before (a foot
                    // rolling over its ball at a toe-off moves its ankle without sliding).
                    let before = |name: &String| at(&target, &shown[j - 1].0, name);
                    let contact = (contacts[i].iter())
                        .min_by(|a, b| before(a).y.total_cmp(&before(b).y))
                        .unwrap_or(foot);
                    let d = at(&target, &shown[j].0, contact) - before(contact);
                    worst_drift = worst_drift.max((d.x * d.x + d.z * d.z).sqrt());
                }
            } else if !state {
                let d = span[span.len() - 1] - span[0];
                lifted_travel = lifted_travel.max((d.x * d.x + d.z * d.z).sqrt());
            }
        }
        println!(
            "{foot}: planted drift ≤ {:.3} mm per tick, lifted travel up to {lifted_travel:.3} m",
            1000.0 * worst_drift
        );
        assert!(
            worst_drift <= 0.0005,
            "{foot} slid {worst_drift} m in a tick"
        );
        assert!(
            lifted_travel > 0.1,
            "{foot} lifted travelled {lifted_travel} m"
        );
    }
    assert!(judged >= 2, "{judged} plants judged");
    assert!(events >= 3, "{events} footplants events");
    println!(
        "{ticks} ticks, {judged} plants judged, {events} events in {:.2} s of wall time",
        wall.elapsed().as_secs_f64()
    );
}

#[test]
fn a_live_graft_walks_its_loop_and_survives_a_loss_on_a_simulated_clock() {
    let Some((labels, walk, _)) = common::first_walk() else {
        return;
    };
    // The walk's left arm by its labels (shoulder, elbow and wrist joints).
    let arm: Option<Vec<&str>> = ["upperArm.L", "lowerArm.L", "hand.L"]
        .iter()
        .map(|r| labels.bone(r))
        .collect();
    let Some(Ok(source_arm)) = arm.map(<[&str; 3]>::try_from) else {
        println!("SKIP: {} has no labelled left arm", labels.rel);
        return;
    };
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let upper = map(&walk, &target, RootMotion::InPlace);
    let lower = map(&walk, &target, RootMotion::Scaled);
    let (wa, ta) = (
        analyze(&SkeletonView::from_clip(&walk.skeleton, &walk.poses)),
        analyze(&SkeletonView::rest(&target)),
    );
    let foot_lock = FootLock::new(&lower, &wa, &ta, LockSettings::default());
    let graft = LiveGraft::new(&upper, lower, &wa, &ta, Some(&walk)).unwrap();
    let stride = graft.gait.as_ref().unwrap().stride_secs();
    let mut rig = Rig::new(
        &walk,
        &target,
        BuiltMapping {
            mapping: upper,
            foot_lock,
            graft: Some(graft),
        },
    );
    // The upper source plays the walk from its middle (its arms swing), at the tick rate.
    let offset = walk.duration_secs() / 2.0;
    let live = (2.5 * stride / TICK.as_secs_f64()) as usize;
    let (mut shown, mut sent) = (Vec::new(), Vec::new());
    for k in 0..live {
        let pose = pose_at(&walk, offset + k as f64 * TICK.as_secs_f64());
        rig.tick(Some(pose));
        shown.push(rig.shown());
        sent.push(pose.clone());
    }
    let pelvis = |p: &Pose| at(&target, p, "pelvis");
    let travelled = (pelvis(&shown[live - 1]) - pelvis(&shown[0])).length();
    // The hips walk on continuously, across the stride's seam (as a client sees them in
    // `tests/tests/graft_live.rs`).
    let flat = |v: glam::Vec3| glam::Vec3::new(v.x, 0.0, v.z);
    let largest_step = (shown.windows(2))
        .map(|w| flat(pelvis(&w[1]) - pelvis(&w[0])).length())
        .fold(0.0f32, f32::max);
    // The elbow bends as the upper source's does (the lower body cannot move it).
    let source_elbow = |p: &Pose| elbow(&walk.skeleton, p, &source_arm);
    let target_elbow = |p: &Pose| elbow(&target, p, &ELBOW_TARGET);
    let a: Vec<f32> = sent.iter().map(source_elbow).collect();
    let b: Vec<f32> = shown.iter().map(target_elbow).collect();
    let r = pearson(&a, &b);
    println!(
        "{live} ticks over {:.2} strides: travelled {travelled:.2} m, largest hip step {largest_step:.3} m, elbow r {r:.3}",
        live as f64 * TICK.as_secs_f64() / stride
    );
    assert!(travelled > 0.5, "the character travelled {travelled} m");
    assert!(largest_step < 0.1, "a jump of {largest_step} m");
    assert!(r >= 0.9, "elbow correlation {r:.3}");

    // The upper source is lost: the character eases to its rest on the spot, then blends back.
    rig.source_state(SourceState::Lost);
    let before = pelvis(&rig.shown());
    let mut motions = Vec::new();
    for _ in 0..60 {
        rig.tick(None);
        motions.push(rig.target.stats.motion.load());
    }
    assert!(
        motions.iter().all(|m| *m == TargetMotion::Rest),
        "{motions:?}"
    );
    let settled = pelvis(&rig.shown());
    let moved = ((settled - before) * glam::Vec3::new(1.0, 0.0, 1.0)).length();
    assert!(moved < 0.01, "the eased character slid {moved} m");
    rig.source_state(SourceState::Live);
    motions.clear();
    for k in 0..60 {
        rig.tick(Some(pose_at(&walk, offset + k as f64 * TICK.as_secs_f64())));
        motions.push(rig.target.stats.motion.load());
    }
    assert_eq!(motions[0], TargetMotion::Resuming);
    assert_eq!(motions[59], TargetMotion::Live, "{motions:?}");
}

/// Shoulder, elbow and wrist of the mannequin's left arm.
const ELBOW_TARGET: [&str; 3] = ["upperarm_l", "lowerarm_l", "hand_l"];

/// The bend at the middle joint of `names`, degrees.
fn elbow(skel: &Skeleton, p: &Pose, names: &[&str; 3]) -> f32 {
    let (s, e, h) = (
        at(skel, p, names[0]),
        at(skel, p, names[1]),
        at(skel, p, names[2]),
    );
    (e - s).angle_between(h - e).to_degrees()
}

fn pearson(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len() as f32;
    let (ma, mb) = (a.iter().sum::<f32>() / n, b.iter().sum::<f32>() / n);
    let cov: f32 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f32 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f32 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt().max(1e-12)
}
