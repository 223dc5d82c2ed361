//! Replay's per-frame call allocates nothing (counted with a global allocator).
#![allow(clippy::unwrap_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use rigcast_sources::{embedded_demo, Replay, ReplayOptions};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
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
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let mut played = 0usize;
    for k in 0..10_000 {
        played += replay.sample(k as f64 * 0.0123, &mut pose).unwrap();
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(after - before, 0);
    assert!(played > 0);
}
