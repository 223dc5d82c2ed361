//! The tick allocates exactly one shared buffer per subject per tick in steady state (frame
//! encoding, retargeting a target subject with its foot lock, VMC encoding and sending with humanoid names,
//! broadcast and stats reuse their memory). Proven with a counting global allocator, so this
//! file holds only this test.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;

use rigcast_engine::clock::TickTime;
use rigcast_engine::performer::{BuiltMapping, Performer};
use rigcast_engine::settings::OnLost;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::{TickContext, Ticker, VmcTarget};
use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::footplant::{FootLock, LockSettings};
use rigcast_server::stats::Stats;
use rigcast_server::tick_task::HostOutput;

mod common;

#[path = "common/counting.rs"]
mod counting;

#[test]
fn tick_allocates_one_buffer_per_subject() {
    let clip = rigcast_server::demo::procedural_clip(30, 30.0).unwrap();
    let mut subjects = Vec::new();
    let mut senders = Vec::new();
    for id in 0..3u32 {
        let (s, tx) = Subject::new(id, format!("s{id}"), clip.skeleton.clone());
        tx.send_modify(|f| {
            f.pose.copy_from(&clip.poses[id as usize]);
            f.seq = 1;
            f.capture_nanos = 1;
        });
        subjects.push(Arc::new(s));
        senders.push(tx);
    }
    // A target subject (the built-in mannequin) retargeted from subject 0.
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let (table, mapping) = common::rest_mapping(&clip.skeleton, &target);
    assert!(table.num_mapped() > 10);
    let (t, target_tx) = common::target_subject(3, &target);
    assert!(!t.shape().vmc.bones.is_empty());
    // With the foot lock, as the server runs a humanoid character by default.
    let foot_lock = FootLock::new(
        &mapping,
        &analyze(&SkeletonView::rest(&clip.skeleton)),
        &analyze(&SkeletonView::rest(&target)),
        LockSettings::default(),
    );
    assert!(foot_lock.is_some());
    let mailbox = Arc::new(std::sync::Mutex::new(Some(BuiltMapping {
        mapping,
        foot_lock,
        graft: None,
    })));
    let performer = Performer::new(
        t.clone(),
        target_tx,
        vec![subjects[0].clone()],
        mailbox,
        OnLost::Ease,
    );
    let target_subject = t.clone();
    subjects.push(t);
    let (frames, mut rx) = tokio::sync::broadcast::channel(1024);
    let receiver = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    socket.set_nonblocking(true).unwrap();
    let mut out = HostOutput {
        frames,
        vmc_socket: Some(socket),
        stats: Arc::new(Stats::default()),
    };
    let mut ticker = Ticker::new(TickContext {
        subjects: Arc::new(subjects),
        vmc: vec![
            VmcTarget {
                addr: receiver.local_addr().unwrap(),
                subject_index: 0,
            },
            VmcTarget {
                addr: receiver.local_addr().unwrap(),
                subject_index: 3,
            },
        ],
        performers: vec![performer],
    });
    // The source moves every tick, so the target is retargeted every tick.
    let advance = |k: usize| {
        senders[0].send_modify(|f| {
            f.pose.copy_from(&clip.poses[k % clip.poses.len()]);
            f.seq += 1;
        });
    };
    // Warm up: buffers grow to size, the performer takes its mapping.
    for k in 0..3 {
        advance(k);
        ticker.tick(TickTime::now(), &mut out);
    }
    let target_seq = target_subject.latest.borrow().seq;
    let before = counting::allocations();
    const TICKS: usize = 100;
    for k in 0..TICKS {
        advance(k + 3);
        ticker.tick(TickTime::now(), &mut out);
    }
    let allocations = counting::allocations() - before;
    assert_eq!(
        allocations,
        TICKS * 4,
        "one shared frame per subject per tick"
    );
    // The frames went out, and the target was retargeted on every tick.
    assert!(rx.try_recv().is_ok());
    assert_eq!(
        target_subject.latest.borrow().seq,
        target_seq + TICKS as u64
    );
}
