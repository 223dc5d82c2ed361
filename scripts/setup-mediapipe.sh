#!/usr/bin/env bash
# Prepares the anchor the vision tests and benchmarks compare rigcast with: MediaPipe Pose 0.10.14
# (PyPI) in a private venv, a program rigcast shares no code with.
#
#   $RIGCAST_HOME/mediapipe-0.10.14/bin/python   (RIGCAST_HOME defaults to ~/.cache/rigcast)
#
# The wheel ships only the full landmark model and downloads lite on first use, which a machine
# without general internet cannot: lite is taken from the npm package scripts/setup-vision.sh uses.
# Idempotent. RIGCAST_SKIP_MEDIAPIPE=1 skips it (the comparisons then skip with a printed reason).
set -euo pipefail

MEDIAPIPE_VERSION="0.10.14"
NPM_POSE_VERSION="0.5.1675469404"
VENV="${RIGCAST_HOME:-$HOME/.cache/rigcast}/mediapipe-$MEDIAPIPE_VERSION"

[[ "${RIGCAST_SKIP_MEDIAPIPE:-0}" == "1" ]] && { echo "setup-mediapipe: RIGCAST_SKIP_MEDIAPIPE=1, skipping"; exit 0; }
if ! "$VENV/bin/python" -c "import mediapipe" >/dev/null 2>&1; then
    echo "setup-mediapipe: creating $VENV with mediapipe $MEDIAPIPE_VERSION" >&2
    mkdir -p "$(dirname "$VENV")"
    python3 -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q "mediapipe==$MEDIAPIPE_VERSION"
fi
MP_DIR=$("$VENV/bin/python" -c "import mediapipe, os; print(os.path.dirname(mediapipe.__file__))")
LITE="$MP_DIR/modules/pose_landmark/pose_landmark_lite.tflite"
if [[ ! -f "$LITE" ]]; then
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    (cd "$tmp" && npm pack --silent "@mediapipe/pose@$NPM_POSE_VERSION" >/dev/null 2>&1 \
        && tar xzf mediapipe-pose-*.tgz)
    cp "$tmp/package/pose_landmark_lite.tflite" "$LITE"
fi
