#!/bin/sh
# rustc wrapper for scripts/fuzz-coverage.sh (as RUSTC_WORKSPACE_WRAPPER): compiles the rigcast
# library crates with LLVM SanitizerCoverage — a counter per edge (inline 8-bit counters) and a
# table of the edges' addresses — and everything else (the fuzz harness, build scripts) as is.
# The harness stays plain so its own branches never look like new behaviour of a reader.
rustc="$1"
shift
case " $* " in
*" --crate-name rigcast_protocol "* | *" --crate-name rigcast_retarget "* | \
    *" --crate-name rigcast_sources "* | *" --crate-name rigcast_server "*)
    exec "$rustc" "$@" -Cpasses=sancov-module \
        -Cllvm-args=-sanitizer-coverage-level=3 \
        -Cllvm-args=-sanitizer-coverage-inline-8bit-counters \
        -Cllvm-args=-sanitizer-coverage-pc-table
    ;;
esac
exec "$rustc" "$@"
