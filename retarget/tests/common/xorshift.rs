//! xorshift64: a deterministic generator with no dependency, for the seeded fuzz tests of the
//! parsers (`retarget/tests/fuzz_parsers.rs`, and `protocol/tests/fuzz_parsers.rs`, which
//! includes this file by path), so a failure reproduces with the printed case number.
#![allow(dead_code)]

/// xorshift64 state; never seed it with 0.
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    /// One of `items` (not empty).
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}
