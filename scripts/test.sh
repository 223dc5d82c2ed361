#!/usr/bin/env bash
# Runs every test. Installs what it needs first.
set -euo pipefail
cd "$(dirname "$0")/.."
# Vision assets (ffmpeg, ONNX Runtime, BlazePose models, pose2sim footage); idempotent, and
# RIGCAST_SKIP_VISION=1 skips it (the vision tests then skip too).
./scripts/setup-vision.sh
cargo test --workspace
