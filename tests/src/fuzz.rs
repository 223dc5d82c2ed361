//! A small mutation fuzzer for the readers and decoders (stable Rust, no dependency): seeds
//! (real files, recordings, valid messages) are mutated by bit flips, byte replacement, hostile
//! tokens, truncation, and duplicated, deleted or spliced spans, for a time budget per target.
//! A panic is a failure: the input is written to a file and named.
//!
//! Built with SanitizerCoverage (`scripts/fuzz-coverage.sh`), it is coverage-guided: an input
//! that reaches a new edge (or a new hit-count bucket of one) joins the corpus, and the run
//! reports the edges it reached ([`crate::coverage`]). Built plainly (CI), it runs blind, and
//! "distinct outcomes" (the first words of each error, or `ok`) tells how far it got.

use std::collections::BTreeSet;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use crate::coverage;

/// Most inputs a coverage-guided run keeps (seeds included).
const MAX_CORPUS: usize = 4096;

/// Largest input a mutation may grow to: the biggest seed's size doubled, at least this.
const MIN_INPUT_CAP: usize = 64 * 1024;

/// Coverage counters are process-wide: instrumented runs take turns.
static INSTRUMENTED_RUN: Mutex<()> = Mutex::new(());

/// Seconds per target: `RIGCAST_FUZZ_SECS`, else 10 (CI's bounded run).
pub fn budget() -> Duration {
    let secs = std::env::var("RIGCAST_FUZZ_SECS")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(10.0);
    Duration::from_secs_f64(secs)
}

/// xorshift64*: deterministic per seed, so a run repeats.
pub struct Rng(pub u64);

impl Rng {
    /// The next value.
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in `0..n` (0 for an empty range).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
}

/// Tokens that stress number, keyword and structure parsing.
const HOSTILE: [&[u8]; 16] = [
    b"NaN",
    b"inf",
    b"-1e39",
    b"1e300",
    b"3e38",
    b"99999999999999999999",
    b"{",
    b"}",
    b"[[[[[[[[",
    b"\xff\xfe",
    b"\0\0\0\0",
    b"\xff\xff\xff\x7f",
    b"JOINT a\n{\n",
    b"\"children\":[0]",
    b"#bundle\0",
    b"\r\n\r\n",
];

/// One mutation of `base` (with a chance of splicing in part of `other`).
pub fn mutate(rng: &mut Rng, base: &[u8], other: &[u8]) -> Vec<u8> {
    let mut out = base.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = out.len();
        match rng.below(8) {
            0 if len > 0 => {
                let i = rng.below(len);
                out[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                out[i] = rng.next() as u8;
            }
            2 => {
                let t = HOSTILE[rng.below(HOSTILE.len())];
                let i = rng.below(len + 1);
                out.splice(i..i, t.iter().copied());
            }
            3 if len > 0 => out.truncate(rng.below(len)),
            4 if len > 0 => {
                let a = rng.below(len);
                let b = (a + 1 + rng.below(64)).min(len);
                let span = out[a..b].to_vec();
                let at = rng.below(len + 1);
                out.splice(at..at, span);
            }
            5 if len > 0 => {
                let a = rng.below(len);
                let b = (a + 1 + rng.below(64)).min(len);
                out.drain(a..b);
            }
            6 if !other.is_empty() => {
                let a = rng.below(other.len());
                let b = (a + 1 + rng.below(256)).min(other.len());
                let at = rng.below(len + 1);
                out.splice(at..at, other[a..b].iter().copied());
            }
            _ if len >= 4 => {
                // A little-endian or big-endian length/count field set to an extreme.
                let i = rng.below(len - 3);
                let v: [u8; 4] = [0xff, 0xff, 0xff, 0x7f];
                out[i..i + 4].copy_from_slice(&v);
            }
            _ => {}
        }
    }
    out
}

/// What one target's run did.
#[derive(Debug)]
pub struct Report {
    /// Target name.
    pub name: String,
    /// Inputs decoded.
    pub executions: u64,
    /// Distinct outcomes seen (`ok`, or the first words of each error).
    pub outcomes: usize,
    /// In an instrumented build: edges reached (by seeds and mutations), of all instrumented.
    pub edges: Option<(usize, usize)>,
    /// Inputs in the corpus at the end (seeds, plus those that reached something new).
    pub corpus: usize,
}

/// Runs `decode` on mutations of `seeds` for `budget`. `decode` returns its outcome (`"ok"`
/// or the error's text, of which the first four words are kept). Every seed must decode
/// unmutated (`seeds_ok`), so the run is known to reach the real reader. A panic writes the
/// input under the target folder and fails the calling test. In an instrumented build, inputs
/// that reach new edges join the corpus, and with `RIGCAST_FUZZ_COVERAGE_DIR` set the edges
/// reached are written to `NAME.edges` there ([`coverage::write_edges`]).
pub fn run(
    name: &str,
    seeds: &[Vec<u8>],
    budget: Duration,
    seeds_ok: bool,
    mut decode: impl FnMut(&[u8]) -> String,
) -> Report {
    assert!(!seeds.is_empty(), "{name}: no seeds");
    let guided = coverage::instrumented();
    // A test that panicked while holding the turn poisons nothing this run relies on.
    let _turn = guided.then(|| INSTRUMENTED_RUN.lock().unwrap_or_else(|e| e.into_inner()));
    let mut seen = coverage::Seen::default();
    coverage::reset();
    if seeds_ok {
        for (i, s) in seeds.iter().enumerate() {
            let outcome = decode(s);
            assert_eq!(outcome, "ok", "{name}: seed {i} does not decode: {outcome}");
        }
    } else {
        for s in seeds {
            decode(s);
        }
    }
    seen.absorb();
    let cap = seeds
        .iter()
        .map(Vec::len)
        .max()
        .unwrap_or(0)
        .saturating_mul(2)
        .max(MIN_INPUT_CAP);
    let mut corpus = seeds.to_vec();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ name.len() as u64);
    let mut outcomes = BTreeSet::new();
    let mut executions = 0u64;
    let start = Instant::now();
    while start.elapsed() < budget {
        let base = &corpus[rng.below(corpus.len())];
        let other = &corpus[rng.below(corpus.len())];
        let mut input = mutate(&mut rng, base, other);
        input.truncate(cap);
        match catch_unwind(AssertUnwindSafe(|| decode(&input))) {
            Ok(outcome) => {
                let class: String = outcome
                    .split_whitespace()
                    .take(4)
                    .collect::<Vec<_>>()
                    .join(" ");
                // Numbers (lines, offsets, counts) would make every error distinct.
                let class: String = class.chars().filter(|c| !c.is_ascii_digit()).collect();
                outcomes.insert(class);
            }
            Err(_) => {
                let path = crash_path(name, executions);
                // Best effort: the failure below names the case either way.
                let _ = std::fs::write(&path, &input);
                panic!(
                    "{name}: panic on input {} ({} bytes), saved to {}",
                    executions,
                    input.len(),
                    path.display()
                );
            }
        }
        if guided && seen.absorb() && corpus.len() < MAX_CORPUS {
            corpus.push(input);
        }
        executions += 1;
    }
    let report = Report {
        name: name.to_string(),
        executions,
        outcomes: outcomes.len(),
        edges: guided.then(|| (seen.hit(), coverage::edges())),
        corpus: corpus.len(),
    };
    if guided {
        write_coverage(name, &seen);
    }
    let edges = report
        .edges
        .map(|(hit, all)| {
            format!(
                ", {hit} of {all} instrumented edges reached, corpus {}",
                report.corpus
            )
        })
        .unwrap_or_default();
    println!(
        "fuzz {}: {} executions in {:.0} s, {} distinct outcomes{edges}",
        report.name,
        report.executions,
        start.elapsed().as_secs_f64(),
        report.outcomes
    );
    report
}

/// Writes the edges a run reached where `RIGCAST_FUZZ_COVERAGE_DIR` says, if it says.
fn write_coverage(name: &str, seen: &coverage::Seen) {
    let Some(dir) = std::env::var_os("RIGCAST_FUZZ_COVERAGE_DIR") else {
        return;
    };
    let path = PathBuf::from(dir).join(format!("{name}.edges"));
    if let Err(e) = coverage::write_edges(&path, seen) {
        panic!("cannot write {}: {e}", path.display());
    }
}

fn crash_path(name: &str, case: u64) -> PathBuf {
    let dir = std::env::temp_dir().join("rigcast-fuzz-crashes");
    // If the folder cannot be made the write fails and the panic message still names the case.
    let _ = std::fs::create_dir_all(&dir);
    dir.join(format!("{name}-{case}.bin"))
}

/// Files under `dir` (recursively, at most `max` of them, none over `max_bytes`) whose name
/// ends with one of `extensions`, in path order.
pub fn corpus(
    dir: &std::path::Path,
    extensions: &[&str],
    max: usize,
    max_bytes: u64,
) -> Vec<Vec<u8>> {
    let mut paths = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if extensions
                .iter()
                .any(|x| p.to_string_lossy().to_ascii_lowercase().ends_with(x))
                && e.metadata().is_ok_and(|m| m.len() <= max_bytes)
            {
                paths.push(p);
            }
        }
    }
    paths.sort();
    paths.truncate(max);
    paths.iter().filter_map(|p| std::fs::read(p).ok()).collect()
}
