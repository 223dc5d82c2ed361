//! A performer walking its idle graph (its source lost) allocates nothing per tick: the
//! take-over (nearest node) and every step after it write into buffers sized at start. Proven
//! with a counting global allocator, so this file holds only this test.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::Duration;

use rigcast_engine::clock::TickTime;
use rigcast_engine::idle_graph::IdleGraph;
use rigcast_engine::performer::{BuiltMapping, Performer};
use rigcast_engine::settings::OnLost;
use rigcast_engine::subject::Subject;
use rigcast_protocol::SourceState;
use rigcast_retarget::graph::{GraphSettings, MotionGraph};

mod common;

#[path = "common/counting.rs"]
mod counting;

#[test]
fn walking_the_idle_graph_allocates_nothing() {
    // The graph: the procedural demo (a looping walk cycle), so no data files are needed.
    let clip = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
    let graph = MotionGraph::build(
        std::slice::from_ref(&clip),
        GraphSettings::default(),
        &mut |_| {},
    )
    .unwrap();
    assert!(graph.num_kept() > 0);
    let target = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let idle = IdleGraph::new(
        &graph,
        std::slice::from_ref(&clip),
        &target,
        None,
        1.0 / 60.0,
    )
    .unwrap();
    let (source, source_tx) = Subject::new(0, "source".into(), clip.skeleton.clone());
    source_tx.send_modify(|f| {
        f.pose.copy_from(&clip.poses[3]);
        f.seq = 1;
        f.capture_nanos = 1;
    });
    let source = Arc::new(source);
    let (_, mapping) = common::rest_mapping(&clip.skeleton, &target);
    let (t, target_tx) = Subject::new(1, "target".into(), target.clone());
    let t = Arc::new(t);
    let mailbox = Arc::new(std::sync::Mutex::new(Some(BuiltMapping {
        mapping,
        foot_lock: None,
        graft: None,
    })));
    let mut performer = Performer::new(
        t.clone(),
        target_tx,
        vec![source.clone()],
        mailbox,
        OnLost::Idle,
    )
    .with_idle_graph(idle, None);
    let mut now = TickTime::now();
    let mut tick = |p: &mut Performer| {
        now = now.after(Duration::from_millis(16));
        p.tick(now);
    };
    for _ in 0..3 {
        tick(&mut performer);
    }
    source.health.set_state(SourceState::Lost);
    // The take-over and the walk, counted from the tick that notices the loss.
    let before = counting::allocations();
    let seq = t.latest.borrow().seq;
    const TICKS: usize = 200;
    for _ in 0..TICKS {
        tick(&mut performer);
    }
    let allocations = counting::allocations() - before;
    assert_eq!(allocations, 0, "the idle walk allocated");
    // It published a new pose on every tick (moving, not settled).
    assert_eq!(t.latest.borrow().seq, seq + TICKS as u64);
}
