#!/usr/bin/env bash
# Glass-to-wire latency of `rigcast serve --source webcam:0 --target builtin:mannequin` through
# the real nokhwa/V4L2 path, against the emulated camera of the tests (sources/tests/v4l2_emu,
# preloaded) serving real footage (640x480 YUYV), with the lite and full models at 30 and 60 fps.
# For each: a WebSocket client (`rigcast loadtest`, its own process, on a real socket) reads the
# stream for SECS seconds; then /v1/status gives the camera's stages (capture, decode, detect,
# landmarks) on the webcam subject and the target's (handoff, retarget, send, glass_to_wire),
# and the client gives capture to arrival of the camera subject's frames. p50 / p99 ms.
# The rows print as BENCHMARKS.md's webcam table has them; glass_to_wire is judged against the
# bound of issue 36: p99 <= one frame interval + the model's time (the landmarks stage's p50 in
# the same run).
#   scripts/bench-webcam.sh [SECS]     (needs gcc, ffmpeg, a release build, the vision models)
# Footage: $RIGCAST_BENCH_VIDEO, else the one-person pose2sim clip scripts/setup-vision.sh
# fetches (cam01). It is played forwards then backwards, 6 s each way at most, so the loop
# has no cut (a camera never jumps; a cut loses the performer and measures the finder instead).
# The server's tick rate: $RIGCAST_BENCH_RATE (default: the server's, 60 Hz); a subset:
# RIGCAST_BENCH_MODELS="lite" RIGCAST_BENCH_FPS="30" (default: lite full, 30 60).
# RIGCAST_BEFORE=<binary> runs that build too, interleaved with this one at every setting (A/B
# in one run, a build column added).
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${1:-20}
BIN=${RIGCAST_BIN:-${CARGO_TARGET_DIR:-target}/release/rigcast}
[[ -x "$BIN" ]] || { echo "build first: cargo build --release --bin rigcast" >&2; exit 1; }
WORK=$(mktemp -d)
SERVER=
trap '[[ -n "$SERVER" ]] && kill "$SERVER" 2>/dev/null; rm -rf "$WORK"' EXIT
VISION=${RIGCAST_HOME:-$HOME/.cache/rigcast}/vision
VIDEO=${RIGCAST_BENCH_VIDEO:-$VISION/pose2sim/cam01.mp4}
[[ -f "$VIDEO" ]] || { echo "no footage at $VIDEO: run scripts/setup-vision.sh" >&2; exit 1; }
RATE=()
[[ -n "${RIGCAST_BENCH_RATE:-}" ]] && RATE=(--rate "$RIGCAST_BENCH_RATE")
gcc -O2 -Wno-format-truncation -shared -fPIC -o "$WORK/emu.so" sources/tests/v4l2_emu/v4l2_emu.c -ldl -lpthread
# Fitted into 640x480 (a portrait clip pillarboxed), then forwards and backwards.
FIT="scale=640:480:force_original_aspect_ratio=decrease,pad=640:480:(ow-iw)/2:(oh-ih)/2,setsar=1"
ffmpeg -v error -t 6 -i "$VIDEO" -an -filter_complex "[0:v]$FIT,split[a][b];[b]reverse[r];[a][r]concat=n=2:v=1" \
    -f rawvideo -pix_fmt yuyv422 "$WORK/vga.yuyv"
mkdir -p "$WORK/state"
cat > "$WORK/cams.conf" <<CONF
device 0 $WORK/state Bench Cam
mode YUYV 640 480 30 $WORK/vga.yuyv
mode YUYV 640 480 60 $WORK/vga.yuyv
CONF
echo "footage: $(basename "$VIDEO"); machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
BUILDS=("$BIN")
[[ -n "${RIGCAST_BEFORE:-}" ]] && BUILDS=("$RIGCAST_BEFORE" "$BIN")
BUILD_HEAD=
[[ ${#BUILDS[@]} -gt 1 ]] && BUILD_HEAD="build | "
echo "| ${BUILD_HEAD}model, fps | capture | decode | detect | landmarks | solve | handoff | retarget | send | glass_to_wire | bound: 1 interval + model | client | load |"
echo "|${BUILD_HEAD:+---|}---|---|---|---|---|---|---|---|---|---|---|---|---|"
for model in ${RIGCAST_BENCH_MODELS:-lite full}; do
    for fps in ${RIGCAST_BENCH_FPS:-30 60}; do
      for build in "${BUILDS[@]}"; do
        port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
        LD_PRELOAD="$WORK/emu.so" RIGCAST_V4L2_EMU="$WORK/cams.conf" XDG_CONFIG_HOME="$WORK/home" \
            "$build" serve --no-mapping-cache --listen "127.0.0.1:$port" "${RATE[@]}" \
            --source "webcam:0?width=640&height=480&fps=$fps&model=$model" \
            --target builtin:mannequin >"$WORK/serve.log" 2>&1 &
        SERVER=$!
        # Until the camera is live and has timed frames (model loading takes a few seconds).
        for _ in $(seq 240); do
            curl -sf "http://127.0.0.1:$port/v1/status" 2>/dev/null | grep -q '"glass_to_pose"' && break
            sleep 0.5
        done
        sleep 2
        load0=$(cut -d' ' -f1 /proc/loadavg)
        "$build" loadtest --url "ws://127.0.0.1:$port/v1/stream" --clients 1 --secs "$SECS" --json >"$WORK/client.json"
        load1=$(cut -d' ' -f1 /proc/loadavg)
        curl -sf "http://127.0.0.1:$port/v1/status" >"$WORK/status.json"
        kill "$SERVER" 2>/dev/null || true
        wait "$SERVER" 2>/dev/null || true
        SERVER=
        python3 - "$(basename "$build")" "$([[ -n "$BUILD_HEAD" ]] && echo 1 || echo 0)" "$model" "$fps" "$load0" "$load1" "$WORK/status.json" "$WORK/client.json" <<'PY'
import json, sys
build, with_build, model, fps, load0, load1, status_path, client_path = sys.argv[1:]
status = json.load(open(status_path))
client = json.load(open(client_path))
stages = {}
camera = None
for s in status["subjects"]:
    cam = (s.get("source") or {}).get("camera")
    if cam:
        camera = s
        stages.update({x["stage"]: x for x in cam["stages"]})
        assert cam["model"] == model, cam
    if s["kind"] == "target":
        stages.update({x["stage"]: x for x in s.get("latency", [])})
cell = lambda n: "%.1f / %.1f" % (stages[n]["p50_ms"], stages[n]["p99_ms"]) if n in stages else "—"
glass = next((g for g in client["glass_us"] if camera and g["subject"] == camera["id"]), None)
arrival = "%.1f / %.1f" % (glass["latency"]["p50"] / 1000, glass["latency"]["p99"] / 1000) if glass else "—"
names = ["capture", "decode", "detect", "landmarks", "solve", "handoff", "retarget", "send"]
if "glass_to_wire" in stages and "landmarks" in stages:
    bound = 1000 / float(fps) + stages["landmarks"]["p50_ms"]
    verdict = "%.1f, %s" % (bound, "met" if stages["glass_to_wire"]["p99_ms"] <= bound else "**missed**")
else:
    verdict = "—"
head = "%s | " % build if with_build == "1" else ""
print("| %s%s, %s | %s | **%s** | %s | %s | %s–%s |" % (head, model, fps, " | ".join(cell(n) for n in names),
      cell("glass_to_wire"), verdict, arrival, load0, load1))
PY
      done
    done
done
