#!/usr/bin/env bash
# Frame rate of `rigcast pose` (decoding included) on the pose2sim footage, lite and full, in one
# run with its baselines, so the figures can be read as ratios on whatever load the machine has:
#
#   - the same binary with the old per-frame path (`--decode-side 0 --finder search --people 1`)
#   - the same binary on the landmark models as converted (all five outputs: segmentation mask
#     and heatmaps computed and thrown away), as rigcast ran them before the pruned copies
#   - RIGCAST_BEFORE=/path/to/rigcast: another build (e.g. of main) run on the same clips;
#     with RIGCAST_PAIRED=N also N rounds of the two in turn (two people), medians and ratio
#   - MediaPipe Python 0.10.14 (its own detector and tracking) on the same decoded frames, one
#     person (`solutions.pose`) and two (the Tasks API's PoseLandmarker, num_poses=2); installed
#     installed by scripts/setup-mediapipe.sh into a venv of its own; RIGCAST_SKIP_MEDIAPIPE=1
#     leaves it out
#
# Usage: scripts/bench-vision.sh [path/to/rigcast]   (default: target/release/rigcast; build it
# with `cargo build --release -p rigcast-server`). Needs scripts/setup-vision.sh to have run.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN="${1:-${CARGO_TARGET_DIR:-target}/release/rigcast}"
ROOT="${RIGCAST_HOME:-$HOME/.cache/rigcast}/vision"
# The two-person demo: 4 cameras × 100 frames, 1088×1920, two performers and a bystander.
CLIPS=("$ROOT"/pose2sim/multi_cam0{1,2,3,4}.mp4)

# A vision home holding only the converted models (no pruned copies), everything else linked.
CONVERTED_HOME=$(mktemp -d)
trap 'rm -rf "$CONVERTED_HOME"' EXIT
mkdir -p "$CONVERTED_HOME/vision/models"
for entry in lib pose2sim READY; do ln -s "$ROOT/$entry" "$CONVERTED_HOME/vision/$entry"; done
for m in lite full heavy; do
    ln -s "$ROOT/models/pose_landmark_$m.onnx" "$CONVERTED_HOME/vision/models/"
done
ln -s "$ROOT/models/pose_detection.onnx" "$CONVERTED_HOME/vision/models/"

# Runs `rigcast pose` over every clip; prints total frames / total seconds.
run() {
    local bin="$1"; shift
    local frames=0 secs=0
    for clip in "${CLIPS[@]}"; do
        line=$("$bin" pose "$clip" --json "$@" 2>&1 >/dev/null | grep -E '^pose: [0-9]+ frames' | tail -1)
        n=$(sed -E 's/^pose: ([0-9]+) frames.*/\1/' <<<"$line")
        fps=$(sed -E 's/.*\(([0-9.]+) fps\).*/\1/' <<<"$line")
        frames=$((frames + n))
        secs=$(python3 -c "print($secs + $n / $fps)")
    done
    python3 -c "print(f'{$frames / $secs:.1f}')"
}

echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
for model in lite full full-int8; do
    two=$(run "$BIN" --model "$model")
    one=$(run "$BIN" --model "$model" --people 1)
    one_thread=$(run "$BIN" --model "$model" --people 1 --threads 1)
    line="$model: rigcast 2 people $two fps | 1 person $one | 1 person on 1 thread $one_thread"
    if [[ "$model" != full-int8 ]]; then
        converted=$(RIGCAST_HOME="$CONVERTED_HOME" run "$BIN" --model "$model" --people 1)
        old_path=$(run "$BIN" --model "$model" --decode-side 0 --finder search --people 1)
        line+=" | converted model (not pruned), 1 person $converted"
        line+=" | old path (full-size decode, search, 1 person) $old_path"
    fi
    echo "$line"
    if [[ -n "${RIGCAST_BEFORE:-}" ]]; then
        echo "$model: before build ($RIGCAST_BEFORE) $(run "$RIGCAST_BEFORE" --model "$model") fps"
    fi
done

# RIGCAST_PAIRED=N (with RIGCAST_BEFORE): N rounds of this build and the other in turn, two
# people with each model, so that a machine whose speed drifts moves both sides of a round alike.
if [[ -n "${RIGCAST_BEFORE:-}" && "${RIGCAST_PAIRED:-0}" -gt 0 ]]; then
    for model in lite full; do
        rounds=()
        for ((i = 0; i < RIGCAST_PAIRED; i++)); do
            rounds+=("$(run "$BIN" --model "$model") $(run "$RIGCAST_BEFORE" --model "$model")")
        done
        printf '%s\n' "${rounds[@]}" | python3 -c "
import statistics, sys
pairs = [tuple(map(float, l.split())) for l in sys.stdin if l.strip()]
this, before = zip(*pairs)
print(f'$model, 2 people, {len(pairs)} paired rounds: this build median {statistics.median(this):.1f} fps '
      f'({min(this):.1f}-{max(this):.1f}), before {statistics.median(before):.1f} '
      f'({min(before):.1f}-{max(before):.1f}), median ratio {statistics.median(a / b for a, b in pairs):.2f}')"
    done
fi

if [[ "${RIGCAST_SKIP_MEDIAPIPE:-0}" != "1" ]]; then
    ./scripts/setup-mediapipe.sh
    VENV="${RIGCAST_HOME:-$HOME/.cache/rigcast}/mediapipe-0.10.14"
    # One person with `solutions.pose`, two with the Tasks API's PoseLandmarker (num_poses=2).
    for model in lite full; do
        for people in 1 2; do
            for clip in "${CLIPS[@]}"; do
                "$VENV/bin/python" scripts/bench_mediapipe.py "$clip" "$model" "$people" 2>/dev/null \
                    | grep '^mediapipe'
            done | python3 -c "
import sys, re
f = s = m = w = 0
for line in sys.stdin:
    n = int(re.search(r'frames=(\d+)', line).group(1))
    f += n
    w += int(re.search(r'with_person=(\d+)', line).group(1))
    s += n / float(re.search(r'fps_with_decoding=([\d.]+)', line).group(1))
    m += n / float(re.search(r'fps_model_only=([\d.]+)', line).group(1))
print(f'$model: mediapipe, people=$people: {f / s:.1f} fps with decoding, {f / m:.1f} fps model only '
      f'({f} frames, all $people found in {w})')"
        done
    done
fi
