#!/usr/bin/env bash
# Coverage-guided fuzzing with a coverage figure per target.
#   scripts/fuzz-coverage.sh [SECONDS_PER_TARGET (default 60)] [TEST_NAME_FILTER... (default fuzz_)]
# Builds tests/tests/fuzz_targets.rs with the rigcast library crates under LLVM
# SanitizerCoverage (scripts/sancov-rustc.sh: an 8-bit counter per edge and the edges'
# addresses; stable rustc, nothing to install but binutils' addr2line), runs the matching
# targets one after another at low priority, then maps the edges each run reached to source
# lines (scripts/fuzz_coverage_report.py). The instrumented crates get a profile setting of
# their own (opt-level 1), so their files never stand in for a plain build's; the
# dependencies are the plain dev build's. Output: RIGCAST_FUZZ_OUT, by default
# $CARGO_TARGET_DIR/fuzz-coverage/ (run.log, NAME.edges, report.md). A panic fails its
# target; the input is saved and named in run.log.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
filters=("${@:2}")
[ ${#filters[@]} -gt 0 ] || filters=(fuzz_)
target_dir=${CARGO_TARGET_DIR:-target}
out=${RIGCAST_FUZZ_OUT:-$target_dir/fuzz-coverage}
mkdir -p "$out"
rm -f "$out"/*.edges

overrides=()
for p in rigcast-protocol rigcast-retarget rigcast-sources rigcast-server; do
    overrides+=(--config "profile.dev.package.$p.opt-level=1")
done
export RUSTC_WORKSPACE_WRAPPER="$PWD/scripts/sancov-rustc.sh"
exe=$(cargo test "${overrides[@]}" -p rigcast-tests --test fuzz_targets --no-run \
    --message-format=json |
    python3 -c 'import json,sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "fuzz_targets" and m.get("executable"):
        print(m["executable"])')
echo "instrumented fuzz targets: $exe"

status=0
RIGCAST_FUZZ_SECS="$secs" RIGCAST_FUZZ_COVERAGE_DIR="$out" \
    nice -n 19 "$exe" --nocapture --test-threads 1 "${filters[@]}" 2>&1 | tee "$out/run.log" ||
    status=$?
python3 scripts/fuzz_coverage_report.py "$out" | tee "$out/report.md"
exit "$status"
