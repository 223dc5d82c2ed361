//! Replay's per-frame call allocates nothing (counted with a global allocator).
//!
//! Only the measuring thread's allocations count: the test harness's own threads allocate
//! concurrently, which made a process-wide count fail at random.
#![allow(clippy::unwrap_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use rigcast_sources::{embedded_demo, Replay, ReplayOptions};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Set on the measuring thread only (const-initialised, so reading it never allocates).
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn sample_allocates_nothing() {
    let replay = Replay::new(embedded_demo().unwrap(), ReplayOptions::default()).unwrap();
    let mut pose = replay.skeleton().rest_pose();
    COUNTING.with(|c| c.set(true));
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let mut played = 0usize;
    for k in 0..10_000 {
        played += replay.sample(k as f64 * 0.0123, &mut pose).unwrap();
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.with(|c| c.set(false));
    assert_eq!(after - before, 0);
    assert!(played > 0);
}
