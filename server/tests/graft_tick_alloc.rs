//! A grafted performer's tick allocates nothing in steady state: the upper source through its
//! mapping, the CMU 131_01 walk looping one stride at a time through the lower mapping, the
//! waist splice and the foot lock on the walk's plants. Proven with a counting global
//! allocator (this file holds only this test), over ticks that are checked to move the
//! character and to cross the stride's seam. Skips when the shared data is absent.
#![allow(clippy::unwrap_used)]

mod common;

use std::sync::Arc;
use std::time::Duration;

use rigcast_engine::graft_live::LiveGraft;
use rigcast_engine::performer::{BuiltMapping, Performer};
use rigcast_engine::settings::OnLost;
use rigcast_engine::subject::Subject;
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings};
use rigcast_retarget::mapping::{auto_map, MapOptions};
use rigcast_retarget::{Mapping, RetargetOptions, RootMotion};

#[path = "common/counting.rs"]
mod counting;

#[test]
fn a_grafted_performer_ticks_without_allocating() {
    // A walk that travels (the bundled demo walks on the spot: its feet never stand still):
    // the first labelled walk, found by its motion (a whole walk is slow in debug: one).
    let Some((_, walk, _)) = common::first_walk() else {
        return;
    };
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let map = |from: &rigcast_retarget::Skeleton, motion| {
        let table = auto_map(
            &SkeletonView::from_clip(from, &walk.poses),
            &SkeletonView::rest(&target),
            &MapOptions::default(),
        );
        let opts = RetargetOptions {
            root_motion: motion,
            ..RetargetOptions::default()
        };
        Mapping::build(&[from], &target, &table, &opts).unwrap()
    };
    // The upper source is the walk too (its arms swing); the lower body is its looping clip.
    let upper = map(&walk.skeleton, RootMotion::InPlace);
    let lower = map(&walk.skeleton, RootMotion::Scaled);
    let (wa, ta) = (
        analyze(&SkeletonView::from_clip(&walk.skeleton, &walk.poses)),
        analyze(&SkeletonView::rest(&target)),
    );
    let foot_lock = FootLock::new(&lower, &wa, &ta, LockSettings::default());
    assert!(foot_lock.is_some());
    let graft = LiveGraft::new(&upper, lower, &wa, &ta, Some(&walk)).unwrap();
    let stride = graft.gait.as_ref().unwrap().stride_secs();
    let (source, source_tx) = Subject::new(0, "walk".into(), walk.skeleton.clone());
    let (t, target_tx) = common::target_subject(1, &target);
    let mailbox = Arc::new(std::sync::Mutex::new(Some(BuiltMapping {
        mapping: upper,
        foot_lock,
        graft: Some(graft),
    })));
    let mut performer = Performer::new(
        t.clone(),
        target_tx,
        vec![Arc::new(source)],
        mailbox,
        OnLost::Ease,
    );
    let advance = |k: usize| {
        source_tx.send_modify(|f| {
            f.pose.copy_from(&walk.poses[k % walk.poses.len()]);
            f.seq += 1;
            f.capture_nanos = 1 + k as u64 * 16_666_667;
        });
    };
    let dt = Duration::from_micros(16_667);
    let mut now = rigcast_engine::clock::TickTime::now();
    for k in 0..3 {
        advance(k);
        performer.tick(now);
        now = now.after(dt);
    }
    let seq = t.latest.borrow().seq;
    let pelvis = target.bone("pelvis").unwrap().index();
    let start = t.latest.borrow().pose.translations[pelvis];
    // Over more than one stride, so the loop's seam is crossed.
    let ticks = ((1.5 * stride) / dt.as_secs_f64()) as usize;
    let before = counting::allocations();
    for k in 0..ticks {
        advance(3 + k);
        performer.tick(now);
        now = now.after(dt);
    }
    let allocated = counting::allocations() - before;
    let moved = (t.latest.borrow().pose.translations[pelvis] - start).length();
    assert_eq!(
        t.latest.borrow().seq,
        seq + ticks as u64,
        "a frame every tick"
    );
    assert!(moved > 0.3, "the character walked {moved} m");
    assert_eq!(allocated, 0, "{allocated} allocations over {ticks} ticks");
}
