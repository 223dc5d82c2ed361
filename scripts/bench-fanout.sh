#!/usr/bin/env bash
# Fan-out and cluster figures for BENCHMARKS.md, all in one run on this machine:
#   1. baseline   — 1 client on node A (direct), 120 Hz, the demo's 2 subjects
#   2. via NATS   — 1 client on node C, which relays A's subjects through nats-server,
#                   measured at the same time as a direct client on A
#   3. 100 / 1000 clients on node A
# Needs nats-server (scripts/install-apps.sh) and builds rigcast in release mode.
# Usage: [RIGCAST_BIN=path] scripts/bench-fanout.sh [SECS]   (default 10 s per measurement)
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-10}"
rate=120

nats_bin="$(command -v nats-server || echo /usr/sbin/nats-server)"
[[ -x "$nats_bin" ]] || { echo "bench-fanout: nats-server not found (scripts/install-apps.sh)"; exit 1; }
# RIGCAST_BIN: measure that binary instead of building this checkout (to compare two builds
# back to back in the same conditions).
if [[ -n "${RIGCAST_BIN:-}" ]]; then
    bin="$RIGCAST_BIN"
else
    cargo build --release --quiet --bin rigcast
    bin="${CARGO_TARGET_DIR:-target}/release/rigcast"
fi

work="$(mktemp -d)"
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$work"; }
trap cleanup EXIT

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

nats_port="$(free_port)"
"$nats_bin" -a 127.0.0.1 -p "$nats_port" -js -sd "$work/js" >"$work/nats.log" 2>&1 &
pids+=($!)
sleep 1

# serve SITE: starts a node; sets $port once it accepts connections.
serve() {
    local site="$1"
    port="$(free_port)"
    XDG_CONFIG_HOME="$work/$site" "$bin" serve --listen "127.0.0.1:$port" --rate "$rate" \
        --no-mapping-cache --nats "nats://127.0.0.1:$nats_port" --site "$site" \
        >"$work/$site.log" 2>&1 &
    pids+=($!)
    for _ in $(seq 100); do
        grep -q "connections:" "$work/$site.log" 2>/dev/null && return
        sleep 0.1
    done
    echo "bench-fanout: node $site did not start:" >&2; cat "$work/$site.log" >&2; exit 1
}

serve a; port_a="$port"   # the demo: a replayed walk and the mannequin retargeted from it
serve c; port_c="$port"   # relays A's two subjects
url() { echo "ws://127.0.0.1:$1/v1/stream"; }
load() { "$bin" loadtest --url "$(url "$1")" --clients "$2" --secs "$secs" --json; }

echo "load average: $(cut -d" " -f1-3 /proc/loadavg)"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo "tick: $rate Hz, 2 subjects, $secs s per measurement"
cat >"$work/summary.py" <<'PY'
import json, sys
label, path, base_path = sys.argv[1], sys.argv[2], sys.argv[3]
r, base = json.load(open(path)), json.load(open(base_path))["latency_us"]
lat, rate = r["latency_us"], r["client_rate_hz"]
ratio = lambda q: lat[q] / max(base[q], 1)
print(f"{label:<26} {r['connected']:>5}/{r['clients']:<5} "
      f"per subject {r['subject_rate_hz']:6.1f} Hz (slowest client {rate['min'] / 2:6.1f})  "
      f"p50 {lat['p50'] / 1000:6.2f} ms  p99 {lat['p99'] / 1000:6.2f} ms  "
      f"max {lat['max'] / 1000:7.2f} ms  lagged {r['lagged']}  missed {r['missed_frames']}  "
      f"x baseline: p50 {ratio('p50'):.2f} p99 {ratio('p99'):.2f}")
PY
# summary LABEL REPORT: one line, with its latencies as ratios to the baseline's of this run.
summary() { python3 "$work/summary.py" "$1" "$2" "$work/base.json"; }

load "$port_a" 1 >"$work/base.json"
summary "baseline (1 client, A)" "$work/base.json"
load "$port_a" 1 >"$work/direct.json" &
direct=$!
load "$port_c" 1 >"$work/nats.json"
wait "$direct"
summary "direct, same run (A)" "$work/direct.json"
summary "through NATS (C)" "$work/nats.json"
load "$port_a" 100 >"$work/c100.json"
summary "100 clients (A)" "$work/c100.json"
load "$port_a" 1000 >"$work/c1000.json"
summary "1000 clients (A)" "$work/c1000.json"
