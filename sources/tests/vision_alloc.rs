//! The vision per-frame path in steady state allocates nothing: decoding into the frame, the
//! ROI crop into the model's input, the landmark model, landmark post-processing and solving
//! to a pose, for two tracked people on real footage (counted with a global allocator).
//!
//! Only the measuring thread's allocations count (the read-ahead decoder thread has its own
//! proof in `read_ahead.rs`; the harness's threads allocate concurrently). ONNX Runtime's own
//! C++ allocations bypass Rust's allocator: with `scripts/count-ort-mallocs.sh` (which preloads
//! a C allocation counter) this test also reports them, running inference on the measuring
//! thread alone so that all of them are seen.
#![allow(clippy::unwrap_used)] // tests may unwrap

#[path = "vision_common.rs"]
mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use common::{assets_or_skip, default_config_or_skip};
use rigcast_sources::vision::{
    DecodeSize, FfmpegSource, FrameSource, PipelineConfig, PosePipeline, RgbFrame,
};

struct Counting;

thread_local! {
    /// Set on the measuring thread only (const-initialised, so reading it never allocates).
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    /// This thread's count: the two tests measure at the same time, each its own thread.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn note_allocation() {
    if COUNTING.with(Cell::get) {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_allocation();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note_allocation();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The C allocation counter of `scripts/malloc-count.c`, when it is preloaded.
#[derive(Clone, Copy)]
struct CHeap {
    counting: extern "C" fn(i32),
    count: extern "C" fn() -> u64,
}

extern "C" {
    fn dlsym(
        handle: *mut std::ffi::c_void,
        symbol: *const std::ffi::c_char,
    ) -> *mut std::ffi::c_void;
}

fn c_heap() -> Option<CHeap> {
    // SAFETY: dlsym with RTLD_DEFAULT (null on glibc) and NUL-terminated names; the symbols,
    // when found, are the shim's functions with exactly these signatures.
    unsafe {
        let on = dlsym(std::ptr::null_mut(), c"rigcast_malloc_counting".as_ptr());
        let count = dlsym(std::ptr::null_mut(), c"rigcast_malloc_count".as_ptr());
        if on.is_null() || count.is_null() {
            return None;
        }
        Some(CHeap {
            counting: std::mem::transmute::<*mut std::ffi::c_void, extern "C" fn(i32)>(on),
            count: std::mem::transmute::<*mut std::ffi::c_void, extern "C" fn() -> u64>(count),
        })
    }
}

/// Rust allocations made by `f` on this thread, and C heap allocations (Rust's included) when
/// the counter is preloaded.
fn counted<T>(c_heap: Option<CHeap>, f: impl FnOnce() -> T) -> (T, usize, u64) {
    let c_before = c_heap.map(|c| {
        (c.counting)(1);
        (c.count)()
    });
    COUNTING.with(|c| c.set(true));
    let before = ALLOCATIONS.with(Cell::get);
    let out = f();
    let after = ALLOCATIONS.with(Cell::get);
    COUNTING.with(|c| c.set(false));
    let c_count = match (c_heap, c_before) {
        (Some(c), Some(b)) => {
            (c.counting)(0);
            (c.count)() - b
        }
        _ => 0,
    };
    (out, after - before, c_count)
}

/// Frames run before counting: the tracker finds both people, buffers reach their sizes.
const WARM_UP_FRAMES: usize = 20;

#[test]
fn two_person_frames_allocate_nothing_in_steady_state() {
    let Some(assets) = assets_or_skip("vision per-frame allocations") else {
        return;
    };
    let c_heap = c_heap();
    let defaults = PipelineConfig::default();
    let config = PipelineConfig {
        assets: assets.clone(),
        // With the C counter, inference stays on this thread so that it sees all of it.
        threads: if c_heap.is_some() {
            1
        } else {
            defaults.threads
        },
        ..defaults
    };
    let mut frames =
        FfmpegSource::open_at(&assets.pose2sim_multi_video(2), DecodeSize::FOR_MODEL, 30.0)
            .unwrap();
    let mut pipeline = PosePipeline::new(&config).unwrap();
    let (w, h) = frames.size();
    let mut frame = RgbFrame::new(w, h);
    let mut pose = pipeline.skeleton().rest_pose();
    for _ in 0..WARM_UP_FRAMES {
        assert!(frames.next_frame(&mut frame).unwrap());
        pipeline.process_frame(&frame).unwrap();
    }
    let stats_before = pipeline.stats();
    let (mut decode, mut process, mut copy) = (0, 0, 0);
    let mut c_process = 0;
    let mut num_frames = 0;
    let mut both_seen = 0;
    loop {
        let (more, n, _) = counted(None, || frames.next_frame(&mut frame).unwrap());
        decode += n;
        if !more {
            break;
        }
        let ((), n, c) = counted(c_heap, || pipeline.process_frame(&frame).unwrap());
        process += n;
        c_process += c;
        let ((), n, _) = counted(None, || {
            if let Some(p) = pipeline.pose(1) {
                pose.copy_from(p);
            }
        });
        copy += n;
        num_frames += 1;
        both_seen += usize::from(pipeline.person(0).is_some() && pipeline.person(1).is_some());
    }
    let stats = pipeline.stats();
    let inferences = stats.inferences - stats_before.inferences;
    let detections = stats.detections - stats_before.detections;
    eprintln!(
        "{num_frames} frames (both people in {both_seen}), {inferences} landmark runs, \
         {detections} detector runs: allocations decode {decode}, process {process}, copy {copy}"
    );
    if c_heap.is_some() {
        let runs = (inferences + detections).max(1);
        eprintln!(
            "C heap allocations in process_frame (ONNX Runtime's and ours): {c_process} in \
             {num_frames} frames = {:.1} per frame, {:.1} per model run",
            c_process as f64 / num_frames as f64,
            c_process as f64 / runs as f64
        );
    } else {
        eprintln!("C heap allocations not counted (run scripts/count-ort-mallocs.sh)");
    }
    assert!(num_frames >= 70, "only {num_frames} frames measured");
    assert!(
        both_seen * 10 >= num_frames * 9,
        "two people tracked in {both_seen}"
    );
    assert_eq!(decode, 0, "decoding into the preallocated frame allocated");
    assert_eq!(copy, 0, "copying a pose out allocated");
    assert_eq!(
        process, 0,
        "tracking + model + post-processing + solving allocated {process} times in \
         {num_frames} frames ({inferences} landmark runs, {detections} detector runs)"
    );
}

/// The fan-out's reading side: a person source waiting for the shared pipeline's next frame
/// and copying its pose out (what the server's source thread does per frame) allocates
/// nothing once the first frame has announced the skeleton.
#[test]
fn person_sources_read_frames_without_allocating() {
    use rigcast_sources::live::{LiveSource, SourceState};
    use rigcast_sources::vision::SharedVision;
    let Some((assets, config)) = default_config_or_skip("person source allocations") else {
        return;
    };
    let frames =
        FfmpegSource::open_at(&assets.pose2sim_multi_video(2), DecodeSize::FOR_MODEL, 30.0)
            .unwrap();
    let shared = SharedVision::new(Box::new(frames), PosePipeline::new(&config).unwrap(), false);
    let mut source = shared.person(1, "#1").unwrap();
    let mut pose = source.skeleton().unwrap().rest_pose();
    let wait = std::time::Duration::from_millis(200);
    let mut warm = 0;
    while warm < WARM_UP_FRAMES {
        warm += usize::from(source.next_frame(wait, &mut pose).unwrap().is_some());
    }
    let (mut produced, mut allocations) = (0, 0);
    for _ in 0..1000 {
        let (meta, n, _) = counted(None, || source.next_frame(wait, &mut pose).unwrap());
        let status = source.status();
        if status.state == SourceState::Lost && status.detail == "end of input" {
            // The call that reports the end of the file (its detail text is allocated once,
            // when the input is over) is not steady state. A loss before that (the person
            // unseen for LOST_AFTER of wall-clock time, as on a loaded machine) is not the
            // end: the frames after it still count.
            break;
        }
        allocations += n;
        produced += usize::from(meta.is_some());
    }
    eprintln!("person #1: {produced} frames read, {allocations} allocations");
    assert!(produced >= 60, "only {produced} frames after the warm-up");
    assert_eq!(allocations, 0, "reading {produced} frames allocated");
}

/// Decoding behind the caller: frames taken as fast as they can be read, after a start where
/// the read-ahead was always full, so every wait below is the caller's first. A channel
/// allocated on a thread's first wait (2 allocations, seen on a loaded CI machine the first time
/// decoding fell behind inference): the hand-over must not.
#[test]
fn waiting_for_the_decoder_allocates_nothing() {
    let Some(assets) = assets_or_skip("decoder wait allocations") else {
        return;
    };
    let mut frames =
        FfmpegSource::open_at(&assets.pose2sim_multi_video(2), DecodeSize::FOR_MODEL, 30.0)
            .unwrap();
    let (w, h) = frames.size();
    let mut frame = RgbFrame::new(w, h);
    for _ in 0..3 {
        // The read-ahead fills while the caller is away: these reads never wait.
        std::thread::sleep(std::time::Duration::from_millis(150));
        assert!(frames.next_frame(&mut frame).unwrap());
    }
    let (mut read, mut allocations) = (0, 0);
    while read < 30 {
        let (more, n, _) = counted(None, || frames.next_frame(&mut frame).unwrap());
        assert!(more, "the clip ended after {read} frames");
        allocations += n;
        read += 1;
    }
    eprintln!("{read} frames read back to back: {allocations} allocations");
    assert_eq!(allocations, 0, "waiting for decoded frames allocated");
}
