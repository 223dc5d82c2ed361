#!/usr/bin/env bash
# Two people of one video driving two characters through `rigcast serve` (release build): the
# pose2sim two-person demo (camera 2) as `#0` and `#1` sharing one pipeline, the built-in
# mannequin and Mixamo's X Bot as targets, one WebSocket client (`rigcast loadtest`) counting
# frames per subject while `/v1/status` is polled for the video subjects' input rate.
# Needs scripts/setup-vision.sh and ../shared/data. Usage: scripts/bench-vision-serve.sh [RATE_HZ]
set -euo pipefail
cd "$(dirname "$0")/.."
rate="${1:-30}"
video="${RIGCAST_VISION_DIR:-$HOME/.cache/rigcast/vision}/pose2sim/multi_cam02.mp4"
xbot="$(cd .. && pwd)/shared/data/zoo/gltf/mixamo_gltf__Xbot.glb"
[[ -f "$video" && -f "$xbot" ]] || { echo "bench-vision-serve: $video or $xbot missing"; exit 1; }
cargo build --release --quiet -p rigcast-server --bin rigcast
bin="${CARGO_TARGET_DIR:-target}/release/rigcast"

work="$(mktemp -d)"
pid=""
cleanup() { [[ -n "$pid" ]] && kill "$pid" 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT
cat >"$work/rigcast.toml" <<TOML
rate_hz = $rate
[[sources]]
kind = "video"
path = "$video"
person = 0
[[sources]]
kind = "video"
path = "$video"
person = 1
[[performers]]
source = "multi_cam02#0"
target = "builtin:mannequin"
[[performers]]
source = "multi_cam02#1"
target = "$xbot"
TOML
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
XDG_CONFIG_HOME="$work/home" XDG_CACHE_HOME="$work/cache" "$bin" serve --listen "127.0.0.1:$port" \
    --config "$work/rigcast.toml" >"$work/serve.log" 2>&1 &
pid=$!
for _ in $(seq 600); do
    grep -q "connections:" "$work/serve.log" 2>/dev/null && break
    sleep 0.1
done
cat >"$work/status.py" <<'PY'
import json, sys
s = json.load(sys.stdin)
parts = []
for x in s["subjects"]:
    src = x.get("source")
    if src:
        parts.append(f"{x['name']}: {src['state']} {src['input_fps']:.1f} fps ({src['detail']})")
print("  ".join(parts), f"| output {s['output_rate_hz']:.1f} Hz")
PY
echo "machine: $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg) at start; tick $rate Hz"
"$bin" loadtest --url "ws://127.0.0.1:$port/v1/stream" --clients 1 --secs 3 --json >"$work/load.json" &
load=$!
for _ in $(seq 8); do
    sleep 0.5
    curl -s "http://127.0.0.1:$port/v1/status" | python3 "$work/status.py"
done
wait "$load"
python3 - "$work/load.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"client: {r['subject_rate_hz']:.1f} frames/s per subject (4 subjects), "
      f"latency p50 {r['latency_us']['p50'] / 1000:.2f} ms, p99 {r['latency_us']['p99'] / 1000:.2f} ms")
PY
echo "load average $(cut -d' ' -f1-3 /proc/loadavg) at the end"
