#!/usr/bin/env bash
# Glass-to-pose latency of `rigcast serve --source webcam:0` through the real nokhwa/V4L2 path,
# against the emulated camera of the tests (sources/tests/v4l2_emu, preloaded) serving real
# footage: per stage p50/p99 as /v1/status reports them (capture, decode, detect, landmarks,
# solve, glass_to_pose), at 30 and 60 fps (640x480 YUYV), for SECS seconds each.
#   scripts/bench-webcam.sh [SECS]        (needs gcc, ffmpeg, a release build, the vision models)
# Footage: the first video of ../shared/data/video (or $RIGCAST_BENCH_VIDEO).
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${1:-20}
BIN=${RIGCAST_BIN:-${CARGO_TARGET_DIR:-target}/release/rigcast}
[[ -x "$BIN" ]] || { echo "build first: cargo build --release -p rigcast-server" >&2; exit 1; }
WORK=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$WORK"' EXIT
VIDEO=${RIGCAST_BENCH_VIDEO:-$(ls ../shared/data/video/*.mp4 | head -1)}
gcc -O2 -Wno-format-truncation -shared -fPIC -o "$WORK/emu.so" sources/tests/v4l2_emu/v4l2_emu.c -ldl -lpthread
ffmpeg -v error -ss 1 -i "$VIDEO" -frames:v 150 -vf scale=640:480 -an -f rawvideo -pix_fmt yuyv422 "$WORK/vga.yuyv"
mkdir -p "$WORK/state"
cat > "$WORK/cams.conf" <<CONF
device 0 $WORK/state Bench Cam
mode YUYV 640 480 30 $WORK/vga.yuyv
mode YUYV 640 480 60 $WORK/vga.yuyv
CONF
echo "footage: $(basename "$VIDEO"); machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
for fps in 30 60; do
    port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
    LD_PRELOAD="$WORK/emu.so" RIGCAST_V4L2_EMU="$WORK/cams.conf" XDG_CONFIG_HOME="$WORK/home" \
        "$BIN" serve --no-mapping-cache --listen "127.0.0.1:$port" \
        --source "webcam:0?width=640&height=480&fps=$fps" --target builtin:mannequin >/dev/null 2>&1 &
    sleep "$SECS"
    curl -s "http://127.0.0.1:$port/v1/status" | python3 -c '
import json, sys
fps = sys.argv[1]
for s in json.load(sys.stdin)["subjects"]:
    cam = (s.get("source") or {}).get("camera")
    if cam:
        stages = ", ".join("%s %.1f/%.1f" % (x["stage"], x["p50_ms"], x["p99_ms"]) for x in cam["stages"])
        n = cam["stages"][0]["samples"] if cam["stages"] else 0
        print("%s fps %dx%d %s, lite: %s (p50/p99 ms over %d frames)"
              % (fps, cam["width"], cam["height"], cam["format"], stages, n))
' "$fps"
    kill %1 2>/dev/null || true
    wait 2>/dev/null || true
done
