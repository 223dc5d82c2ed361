//! A performer whose input goes bad past every entry check (written straight into its source's
//! slot) faults alone: the tick goes on, the other performer keeps publishing every tick, the
//! faulted target keeps its last good pose and says why, and it runs again once its input is
//! sane.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::Duration;

use glam::Vec3;
use rigcast_engine::clock::TickTime;
use rigcast_engine::performer::{BuiltMapping, Performer};
use rigcast_engine::settings::OnLost;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::{TickContext, Ticker};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings};
use rigcast_server::stats::Stats;
use rigcast_server::tick_task::HostOutput;

mod common;

#[test]
fn a_performer_fed_overflowing_values_faults_alone_and_recovers() {
    let clip = rigcast_server::demo::procedural_clip(30, 30.0).unwrap();
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let mut performers = Vec::new();
    let (mut subjects, senders) = common::source_subjects(2, &clip.skeleton);
    let mut targets = Vec::new();
    for (k, source) in subjects.clone().iter().enumerate() {
        let (_, mapping) = common::rest_mapping(&clip.skeleton, &target);
        let foot_lock = FootLock::new(
            &mapping,
            &analyze(&SkeletonView::rest(&clip.skeleton)),
            &analyze(&SkeletonView::rest(&target)),
            LockSettings::default(),
        );
        let mailbox = Arc::new(std::sync::Mutex::new(Some(BuiltMapping {
            mapping,
            foot_lock,
            graft: None,
        })));
        let (t, tx) = common::target_subject(2 + k as u32, &target);
        performers.push(Performer::new(
            t.clone(),
            tx,
            vec![source.clone()],
            mailbox,
            OnLost::Ease,
        ));
        targets.push(t.clone());
        subjects.push(t);
    }
    let (frames, _rx) = tokio::sync::broadcast::channel(4096);
    let mut out = HostOutput {
        frames,
        vmc_socket: None,
        stats: Arc::new(Stats::default()),
    };
    let mut ticker = Ticker::new(TickContext {
        subjects: Arc::new(subjects),
        vmc: Vec::new(),
        performers,
    });
    let mut k = 0usize;
    let mut feed = |bad: Option<f32>| {
        for (i, tx) in senders.iter().enumerate() {
            tx.send_modify(|f| {
                f.pose.copy_from(&clip.poses[k % clip.poses.len()]);
                if i == 0 {
                    if let Some(v) = bad {
                        // Each finite (or not), and past the entry checks on purpose.
                        f.pose.translations[0] = Vec3::splat(v);
                    }
                }
                f.seq += 1;
                f.capture_nanos = 1 + k as u64;
            });
        }
        k += 1;
    };
    let seqs = |targets: &[Arc<Subject>]| -> Vec<u64> {
        targets.iter().map(|t| t.latest.borrow().seq).collect()
    };
    for _ in 0..20 {
        feed(None);
        ticker.tick(TickTime::now(), &mut out);
    }
    let good_before = seqs(&targets);
    assert!(good_before.iter().all(|&s| s > 0), "{good_before:?}");
    for bad in [3e38, f32::NAN, f32::INFINITY] {
        for _ in 0..10 {
            feed(Some(bad));
            ticker.tick(TickTime::now(), &mut out);
        }
    }
    let during = seqs(&targets);
    // The other performer published on every one of the 30 ticks.
    assert_eq!(during[1], good_before[1] + 30);
    // The faulted one published nothing bad and says why.
    let shown = targets[0].latest.borrow().pose.clone();
    assert!(shown.translations.iter().all(|t| t.is_finite()));
    assert!(shown.rotations.iter().all(|q| q.is_finite()));
    let fault = targets[0].stats.fault().expect("the target is faulted");
    assert!(!fault.is_empty());
    assert_eq!(
        targets[0]
            .stats
            .faults_total
            .load(std::sync::atomic::Ordering::Relaxed),
        1,
        "one fault episode, not one per tick"
    );
    assert!(targets[1].stats.fault().is_none());
    // Sane input again: after the retry delay it runs and publishes again.
    std::thread::sleep(rigcast_engine::fault::FAULT_RETRY + Duration::from_millis(50));
    for _ in 0..10 {
        feed(None);
        ticker.tick(TickTime::now(), &mut out);
    }
    assert!(targets[0].stats.fault().is_none(), "the fault cleared");
    assert!(seqs(&targets)[0] > during[0], "it publishes again");
}
