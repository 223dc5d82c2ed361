#!/usr/bin/env bash
# The live demo on a fresh Debian 12 machine with Rust: installs what the build needs besides Rust
# (scripts/install-build-deps.sh: libclang-dev, nasm, gcc for the webcam source), then builds and runs
# `rigcast serve`. Arguments go to `rigcast serve`, e.g. `./scripts/demo.sh --source webcam:0`.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-build-deps.sh
exec cargo run --release --bin rigcast -- serve "$@"
