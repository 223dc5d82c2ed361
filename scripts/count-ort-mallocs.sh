#!/bin/sh
# Counts the C heap allocations of the vision per-frame path, ONNX Runtime's included: builds
# scripts/malloc-count.c, preloads it into tests/vision_alloc.rs and prints the per-frame and
# per-model-run counts (Rust's own allocations are counted by the test itself, and must be 0).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
lib=${TMPDIR:-/tmp}/rigcast-malloc-count.so
cc -O2 -shared -fPIC -o "$lib" "$here/scripts/malloc-count.c"
cd "$here"
# The allocator test binary is built first, so that the preload does not count cargo itself.
cargo test -p rigcast-sources --test vision_alloc --no-run
LD_PRELOAD="$lib" cargo test -p rigcast-sources --test vision_alloc -- --nocapture 2>&1 |
    grep -E "allocations|C heap|test result"
