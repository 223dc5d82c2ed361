#!/usr/bin/env bash
# The judge on real footage (sources/tests/vision_footage.rs) in a release build, every frame of
# every clip, lite and full, with issue 32's acceptance bounds asserted: per clip coverage of each
# identity slot, identity jumps, left/right agreement and frame rate with decoding, against
# MediaPipe Pose 0.10.14 (full; one person, and for speed as many people as it finds in the clip,
# up to 2) on the same frames, clip by clip in turn; the 3D
# table of the pose2sim cameras (sources/tests/vision_reference3d.rs) with its bounds. Then the
# frame rate of `rigcast pose` with the defaults against `--people 1` on every clip, the two
# runs alternating clip by clip (the machine's load moves both alike).
#
# Usage: scripts/bench-vision-footage.sh   (needs scripts/setup-vision.sh; installs MediaPipe
# with scripts/setup-mediapipe.sh). RIGCAST_SHARED_DATA=DIR points at the shared data folder
# when the checkout is not beside it; RIGCAST_FOOTAGE_FRAMES=N bounds the frames per clip.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup-mediapipe.sh
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
status=0
for model in lite full; do
    RIGCAST_TEST_MODEL=$model RIGCAST_FOOTAGE_FRAMES="${RIGCAST_FOOTAGE_FRAMES:-0}" \
        cargo test --release -q -p rigcast-sources --test vision_footage -- --ignored --exact \
        default_settings_keep_the_person_against_mediapipe_on_real_footage --nocapture 2>&1 \
        | grep -E '^\||^model|^load|^SKIP|identity|MediaPipe|left/right|detector' || status=1
done
# The 3D table (issue 32, item 4): lite, full and MediaPipe per pose2sim camera against the
# triangulated reference, its bounds asserted.
RIGCAST_FOOTAGE_ACCEPTANCE=1 cargo test --release -q -p rigcast-sources --test vision_reference3d \
    -- --nocapture 2>&1 | grep -E '^\||^reference|^SKIP|^cam|panicked' || status=1

cargo build --release -q -p rigcast-server
BIN="${CARGO_TARGET_DIR:-target}/release/rigcast"
DATA="${RIGCAST_SHARED_DATA:-../shared/data}"
fps() { "$BIN" pose "$@" --json 2>&1 >/dev/null | sed -nE 's/^pose: ([0-9]+) frames, person #0 in ([0-9]+).*\(([0-9.]+) fps\).*/\2 \3/p'; }
echo "| clip | model | person #0 seen, default / --people 1 | fps, default / --people 1 | ratio |"
echo "|---|---|---|---|---|"
for clip in "$DATA"/video/*.{mp4,avi,mkv,mov,webm} "${RIGCAST_HOME:-$HOME/.cache/rigcast}"/vision/pose2sim/*.mp4; do
    [[ -f "$clip" ]] || continue
    for model in lite full; do
        read -r seen_d fps_d <<<"$(fps "$clip" --model "$model")"
        read -r seen_1 fps_1 <<<"$(fps "$clip" --model "$model" --people 1)"
        echo "| $(basename "$clip") | $model | $seen_d / $seen_1 | $fps_d / $fps_1 | $(python3 -c "print(f'{$fps_d / $fps_1:.2f}')") |"
    done
done
echo "load at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
exit $status
