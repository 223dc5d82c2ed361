//! Edge coverage for the fuzzer, when the code under test was compiled with LLVM's
//! SanitizerCoverage (`-C passes=sancov-module`, edge level, inline 8-bit counters and a PC
//! table; `scripts/fuzz-coverage.sh` builds so). Every instrumented object file registers its
//! counters and its table of edge addresses from a constructor before `main`, through the two
//! hooks [`sancov_hooks!`] defines in the fuzz executable. Without instrumentation nothing
//! registers, [`instrumented`] is false and the fuzzer runs blind, as in CI.
//!
//! The counters give the fuzzer feedback (an input that reaches an edge, or an edge's hit
//! count bucket, not seen before joins the corpus, as libFuzzer does), and the PC table lets a
//! run say which source lines it reached: [`write_edges`] writes every edge's address (relative
//! to the executable's load address, as `addr2line` reads it) with whether it was hit.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Most object files that can register (each codegen unit of each instrumented crate is one).
const MAX_MODULES: usize = 1 << 14;

static COUNTER_START: [AtomicUsize; MAX_MODULES] = [const { AtomicUsize::new(0) }; MAX_MODULES];
static COUNTER_LEN: [AtomicUsize; MAX_MODULES] = [const { AtomicUsize::new(0) }; MAX_MODULES];
static PC_TABLE: [AtomicUsize; MAX_MODULES] = [const { AtomicUsize::new(0) }; MAX_MODULES];
static MODULES: AtomicUsize = AtomicUsize::new(0);
static PC_TABLES: AtomicUsize = AtomicUsize::new(0);

/// Defines the two SanitizerCoverage hooks; invoke once in the fuzz test executable (the
/// linker must see them beside the instrumented code: a definition in this library's archive
/// could be passed over before the objects that call it are read).
#[macro_export]
macro_rules! sancov_hooks {
    () => {
        /// Called by each instrumented object file's constructor with its edge counters.
        ///
        /// # Safety
        /// Called by compiler-generated code with the bounds of a static array.
        #[no_mangle]
        pub unsafe extern "C" fn __sanitizer_cov_8bit_counters_init(start: *mut u8, end: *mut u8) {
            $crate::coverage::register_counters(start, end);
        }

        /// Called by the same constructor, after the counters, with their edges' addresses.
        ///
        /// # Safety
        /// Called by compiler-generated code with the bounds of a static array.
        #[no_mangle]
        pub unsafe extern "C" fn __sanitizer_cov_pcs_init(start: *const usize, end: *const usize) {
            $crate::coverage::register_pcs(start, end);
        }
    };
}

/// Records one module's counters (before `main`: atomics only, no allocation).
pub fn register_counters(start: *mut u8, end: *mut u8) {
    let i = MODULES.load(Ordering::Relaxed);
    if i >= MAX_MODULES || end <= start {
        return;
    }
    COUNTER_START[i].store(start as usize, Ordering::Relaxed);
    COUNTER_LEN[i].store(end as usize - start as usize, Ordering::Relaxed);
    MODULES.store(i + 1, Ordering::Release);
}

/// Records the PC table of the module whose counters were registered last. Each entry is two
/// words (address, flags), one per counter, in the counters' order.
pub fn register_pcs(start: *const usize, end: *const usize) {
    let i = PC_TABLES.load(Ordering::Relaxed);
    if i >= MODULES.load(Ordering::Acquire) || end <= start {
        return;
    }
    PC_TABLE[i].store(start as usize, Ordering::Relaxed);
    PC_TABLES.store(i + 1, Ordering::Release);
}

/// Whether any instrumented code registered.
pub fn instrumented() -> bool {
    MODULES.load(Ordering::Acquire) > 0
}

fn modules() -> impl Iterator<Item = &'static mut [u8]> {
    (0..MODULES.load(Ordering::Acquire)).map(|i| {
        let start = COUNTER_START[i].load(Ordering::Relaxed) as *mut u8;
        let len = COUNTER_LEN[i].load(Ordering::Relaxed);
        // SAFETY: the compiler-made counter arrays are static and live for the whole process;
        // instrumented code increments them in place, and the fuzzer reads them on the same
        // thread between inputs.
        unsafe { std::slice::from_raw_parts_mut(start, len) }
    })
}

/// Edges instrumented in all.
pub fn edges() -> usize {
    modules().map(|m| m.len()).sum()
}

/// Zeroes every counter (before an input is run).
pub fn reset() {
    for m in modules() {
        m.fill(0);
    }
}

/// A hit count's bucket as one bit (1, 2, 3, 4-7, 8-15, 16-31, 32-127, 128+), as libFuzzer
/// counts: a loop that runs far more often is new behaviour, one more turn is not.
fn bucket(count: u8) -> u8 {
    match count {
        0 => 0,
        1 => 1,
        2 => 2,
        3 => 4,
        4..=7 => 8,
        8..=15 => 16,
        16..=31 => 32,
        32..=127 => 64,
        _ => 128,
    }
}

/// What one target's run has reached: per edge, the buckets seen.
#[derive(Default)]
pub struct Seen(Vec<u8>);

impl Seen {
    /// Folds the counters of the input just run into `self` and zeroes them; true when the
    /// input reached an edge or a bucket not seen before.
    pub fn absorb(&mut self) -> bool {
        let total = edges();
        if self.0.len() < total {
            self.0.resize(total, 0);
        }
        let mut novel = false;
        let mut base = 0;
        for m in modules() {
            let len = m.len();
            for (n, chunk) in m.chunks_mut(8).enumerate() {
                if chunk.iter().all(|&c| c == 0) {
                    continue;
                }
                for (k, c) in chunk.iter_mut().enumerate() {
                    let b = bucket(*c);
                    *c = 0;
                    let seen = &mut self.0[base + 8 * n + k];
                    if b & !*seen != 0 {
                        *seen |= b;
                        novel = true;
                    }
                }
            }
            base += len;
        }
        novel
    }

    /// Edges reached at least once.
    pub fn hit(&self) -> usize {
        self.0.iter().filter(|&&b| b != 0).count()
    }
}

/// The executable's load address: the start of its first mapping (file offset 0), which the
/// PC table's addresses are relative to once `addr2line` reads the file.
fn load_base() -> Option<usize> {
    let exe = std::fs::read_link("/proc/self/exe").ok()?;
    let exe = exe.to_string_lossy();
    let maps = std::fs::read_to_string("/proc/self/maps").ok()?;
    maps.lines().find_map(|line| {
        let mut f = line.split_whitespace();
        let range = f.next()?;
        let offset = f.nth(1)?;
        let path = f.nth(2)?;
        if path != exe || usize::from_str_radix(offset, 16).ok()? != 0 {
            return None;
        }
        usize::from_str_radix(range.split('-').next()?, 16).ok()
    })
}

/// Writes one line per instrumented edge: its address in the executable (hex, as `addr2line
/// -e EXE` takes it), `1` if `seen` reached it (else `0`), and `1` if it is a function's entry
/// (else `0`; a function's edges follow its entry). The first line names the executable.
pub fn write_edges(path: &std::path::Path, seen: &Seen) -> std::io::Result<()> {
    use std::fmt::Write as _;
    let base = load_base().ok_or_else(|| std::io::Error::other("no load address in /proc"))?;
    let exe = std::fs::read_link("/proc/self/exe")?;
    let mut out = format!("# {}\n", exe.display());
    let tables = PC_TABLES.load(Ordering::Acquire);
    let mut index = 0;
    for (i, m) in modules().enumerate() {
        if i >= tables {
            break;
        }
        let table = PC_TABLE[i].load(Ordering::Relaxed) as *const usize;
        for k in 0..m.len() {
            // SAFETY: the table holds two words per counter of the same module (LLVM's
            // pc-table layout) and is static.
            let (pc, flags) = unsafe { (*table.add(2 * k), *table.add(2 * k + 1)) };
            let hit = seen.0.get(index + k).is_some_and(|&b| b != 0);
            // Writing to a String cannot fail.
            let _ = writeln!(
                out,
                "{:x} {} {}",
                pc.wrapping_sub(base),
                u8::from(hit),
                flags & 1
            );
        }
        index += m.len();
    }
    std::fs::write(path, out)
}
