#!/usr/bin/env bash
# The one test command (README; CI's .ci/run calls it). On a fresh Debian 12 machine it first
# installs what the build and the real-program tests need, then runs every test of the workspace:
#   0. scripts/install-build-deps.sh — libclang-dev, nasm, gcc (the webcam source's build)
#   1. scripts/install-apps.sh  — Blender, Chromium, nats-server from Debian (end-to-end tests)
#   2. scripts/setup-vision.sh  — ffmpeg, ONNX Runtime (PyPI wheel), BlazePose ONNX models
#                                 (npm @mediapipe/pose, converted), real footage (PyPI pose2sim)
#   3. scripts/setup-vmc-check.sh — python-osc (PyPI) in a private venv: the independent VMC
#                                 receiver the VMC output is judged with
#   4. scripts/setup-mediapipe.sh — MediaPipe Pose 0.10.14 (PyPI) in a private venv: the anchor
#                                 the vision judge on real footage compares rigcast with (step 7
#                                 runs the judge as a report, 60 frames a clip, and the 3D table
#                                 of the pose2sim cameras: sources/tests/vision_footage.rs,
#                                 vision_reference3d.rs)
#   5. scripts/setup-bpy.sh     — the official `bpy` wheels (Blender 4.2, 4.5 LTS, 5.0) from PyPI,
#                                 one cached venv each: the add-on's Blender test matrix
#   6. scripts/check_layers.py  — dependencies point down (ARCHITECTURE.md, Layers), and its
#                                 own tests (scripts/test_check_layers.py)
#   7. cargo test --workspace   — unit, integration, end-to-end tests
#                                 (incl. tests/tests/fuzz_targets.rs: each reader and decoder
#                                 under mutation for RIGCAST_FUZZ_SECS, default 10 s each)
# The setup steps are idempotent and skip work already done.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n=== %s ===\n' "$*"; }

step "installing the build's own needs (if missing)"
./scripts/install-build-deps.sh

step "installing Blender, Chromium and nats-server (if missing)"
./scripts/install-apps.sh

step "preparing the vision models and runtime (if missing)"
./scripts/setup-vision.sh

step "preparing the independent VMC receiver (if missing)"
./scripts/setup-vmc-check.sh

step "preparing MediaPipe, the vision anchor (if missing)"
./scripts/setup-mediapipe.sh

step "preparing Blender 4.2, 4.5 and 5.0 as Python modules (if missing)"
./scripts/setup-bpy.sh

step "checking that dependencies point down (ARCHITECTURE.md, Layers)"
python3 scripts/test_check_layers.py
python3 scripts/check_layers.py

step "cargo test --workspace"
# A one-off build gains nothing from incremental state, which would add
# gigabytes to the disk a fresh machine has.
CARGO_INCREMENTAL=0 cargo test --workspace --no-fail-fast
