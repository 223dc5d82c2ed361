#!/usr/bin/env bash
# Prepares everything the webcam/video pose pipeline needs, under one cache directory:
#
#   $RIGCAST_HOME/vision/            (RIGCAST_HOME defaults to ~/.cache/rigcast)
#     lib/libonnxruntime.so          ONNX Runtime 1.31.1, taken from the PyPI wheel
#     models/pose_landmark_{lite,full,heavy}.onnx   BlazePose landmark models (npm @mediapipe/pose,
#                                    converted from TFLite with tf2onnx in a private venv)
#     models/pose_landmark_{lite,full,heavy}_pruned.onnx   the same models with only the outputs
#                                    rigcast reads (no segmentation mask: same landmarks, about
#                                    half the work; scripts/prune_landmark_model.py)
#     models/pose_landmark_full_int8.onnx   full, pruned and quantised to int8 (static QDQ,
#                                    calibrated on the single-person pose2sim clips;
#                                    scripts/quantize_landmark_model.py); only `--model full-int8`
#                                    loads it
#     models/pose_detection.onnx     BlazePose person detector (same npm package: its
#                                    pose_solution_packed_assets.data is pose_detection.tflite;
#                                    sparse fp16 weights made dense by scripts/densify_tflite.py
#                                    first, which tf2onnx cannot read as they are)
#     models/pose_{landmark_lite,landmark_full,landmark_heavy,detection}_planar.onnx
#                                    the pruned landmark models and the detector taking their
#                                    input channels first (the input Pad and Transpose folded
#                                    into the first convolution, scripts/planar_input.py: the
#                                    same outputs, less work); rigcast loads these when there
#     pose2sim/cam01..cam04.mp4      real footage for the acceptance tests (PyPI wheel pose2sim),
#     pose2sim/multi_cam01..04.mp4   and its two-person demo
#     pose2sim/Calib.qca.txt         the single-person demo's four-camera calibration (Qualisys
#                                    export): the 3D reference the vision tests triangulate
#     READY                          written last; the Rust side checks it
#
# It also installs the Debian package ffmpeg (video decoding runs through an ffmpeg child process).
# Live webcam capture (nokhwa/V4L2, in the default build) needs libclang to build; that is
# scripts/install-build-deps.sh's job, not this script's.
# Idempotent: every step is skipped when its output already exists, so the test command runs it
# every time. `rigcast setup vision` runs this script. Set RIGCAST_SKIP_VISION=1 to skip entirely.
set -euo pipefail

if [[ "${RIGCAST_SKIP_VISION:-0}" == "1" ]]; then
    echo "setup-vision: RIGCAST_SKIP_VISION=1, skipping"
    exit 0
fi

ORT_VERSION="1.31.1"
MEDIAPIPE_POSE_VERSION="0.5.1675469404"
POSE2SIM_VERSION="0.10.49"
TF2ONNX_VERSION="1.17.0"
TENSORFLOW_VERSION="2.21.0"
ONNX_VERSION="1.23.2"
NUMPY_VERSION="2.4.6"

ROOT="${RIGCAST_HOME:-$HOME/.cache/rigcast}/vision"
mkdir -p "$ROOT/lib" "$ROOT/models" "$ROOT/pose2sim" "$ROOT/downloads"
log() { echo "setup-vision: $*" >&2; }

# --- ffmpeg -------------------------------------------------------------------------------------
if ! command -v ffmpeg >/dev/null 2>&1; then
    SUDO=""
    [[ "$(id -u)" != "0" ]] && SUDO="sudo"
    log "installing ffmpeg (apt)"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq --no-install-recommends ffmpeg >/dev/null
fi

PY="${PYTHON:-python3}"

# --- ONNX Runtime shared library ----------------------------------------------------------------
if [[ ! -f "$ROOT/lib/libonnxruntime.so" ]]; then
    log "fetching onnxruntime==$ORT_VERSION wheel"
    rm -rf "$ROOT/downloads/ort"
    "$PY" -m pip download -q --no-deps --only-binary=:all: "onnxruntime==$ORT_VERSION" \
        -d "$ROOT/downloads/ort"
    wheel=$(ls "$ROOT/downloads/ort"/onnxruntime-*.whl)
    "$PY" - "$wheel" "$ROOT/lib" <<'EOF'
import sys, zipfile, os
wheel, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    names = [n for n in z.namelist() if "/capi/libonnxruntime.so" in n]
    if not names:
        sys.exit("no libonnxruntime.so in " + wheel)
    name = max(names, key=len)  # the versioned file, not a symlink stub
    tmp = os.path.join(out, "libonnxruntime.so.tmp")
    with z.open(name) as src, open(tmp, "wb") as dst:
        dst.write(src.read())
    os.replace(tmp, os.path.join(out, "libonnxruntime.so"))
EOF
    rm -rf "$ROOT/downloads/ort"
fi

# --- BlazePose landmark models ------------------------------------------------------------------
need_models=()
for m in lite full heavy; do
    [[ -f "$ROOT/models/pose_landmark_$m.onnx" ]] || need_models+=("$m")
done
need_detector=0
[[ -f "$ROOT/models/pose_detection.onnx" ]] || need_detector=1
if [[ ${#need_models[@]} -gt 0 || $need_detector == 1 ]]; then
    if [[ ! -f "$ROOT/downloads/mediapipe/package/pose_landmark_lite.tflite" ]]; then
        log "fetching npm @mediapipe/pose@$MEDIAPIPE_POSE_VERSION"
        rm -rf "$ROOT/downloads/mediapipe"
        mkdir -p "$ROOT/downloads/mediapipe"
        (cd "$ROOT/downloads/mediapipe" && npm pack --silent "@mediapipe/pose@$MEDIAPIPE_POSE_VERSION" >/dev/null 2>&1 \
            && tar xzf mediapipe-pose-*.tgz)
    fi
    VENV="$ROOT/venv"
    if [[ ! -x "$VENV/bin/python" ]] || ! "$VENV/bin/python" -c "import tf2onnx, tensorflow" >/dev/null 2>&1; then
        log "creating converter venv (tensorflow-cpu $TENSORFLOW_VERSION, tf2onnx $TF2ONNX_VERSION)"
        "$PY" -m venv "$VENV"
        "$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null
        "$VENV/bin/python" -m pip install -q "tensorflow-cpu==$TENSORFLOW_VERSION" "tf2onnx==$TF2ONNX_VERSION"
    fi
    for m in "${need_models[@]}"; do
        log "converting pose_landmark_$m.tflite -> onnx"
        out="$ROOT/models/pose_landmark_$m.onnx"
        TF_CPP_MIN_LOG_LEVEL=3 "$VENV/bin/python" -m tf2onnx.convert \
            --tflite "$ROOT/downloads/mediapipe/package/pose_landmark_$m.tflite" \
            --output "$out.tmp" --opset 17 >"$ROOT/downloads/convert_$m.log" 2>&1 \
            || { cat "$ROOT/downloads/convert_$m.log" >&2; exit 1; }
        mv "$out.tmp" "$out"
    done
    if [[ $need_detector == 1 ]]; then
        log "converting pose_detection.tflite -> onnx"
        pkg="$ROOT/downloads/mediapipe/package"
        out="$ROOT/models/pose_detection.onnx"
        cp "$pkg/pose_solution_packed_assets.data" "$ROOT/downloads/pose_detection.tflite"
        TF_CPP_MIN_LOG_LEVEL=3 "$VENV/bin/python" "$(dirname "$0")/densify_tflite.py" \
            "$ROOT/downloads/pose_detection.tflite" "$ROOT/downloads/pose_detection_dense.tflite" \
            >"$ROOT/downloads/convert_detector.log" 2>&1 \
            || { cat "$ROOT/downloads/convert_detector.log" >&2; exit 1; }
        TF_CPP_MIN_LOG_LEVEL=3 "$VENV/bin/python" -m tf2onnx.convert \
            --tflite "$ROOT/downloads/pose_detection_dense.tflite" \
            --output "$out.tmp" --opset 17 >>"$ROOT/downloads/convert_detector.log" 2>&1 \
            || { cat "$ROOT/downloads/convert_detector.log" >&2; exit 1; }
        rm -f "$ROOT/downloads/pose_detection.tflite" "$ROOT/downloads/pose_detection_dense.tflite"
        mv "$out.tmp" "$out"
    fi
    # The converter venv (~1.6 GB) and the npm package are only needed to make the models.
    rm -rf "$VENV" "$ROOT/downloads/mediapipe"
fi

# --- Real footage: pose2sim demo videos ---------------------------------------------------------
# Demo_SinglePerson (cam01..cam04.mp4) and Demo_MultiPerson (multi_cam01..multi_cam04.mp4: two
# people on a platform, a third one in the background; 1088×1920, 60 fps, 100 frames), and the
# single-person demo's calibration of its four cameras.
if [[ ! -f "$ROOT/pose2sim/cam04.mp4" || ! -f "$ROOT/pose2sim/multi_cam04.mp4" \
    || ! -f "$ROOT/pose2sim/Calib.qca.txt" ]]; then
    log "fetching pose2sim==$POSE2SIM_VERSION wheel (demo videos)"
    rm -rf "$ROOT/downloads/pose2sim"
    "$PY" -m pip download -q --no-deps "pose2sim==$POSE2SIM_VERSION" -d "$ROOT/downloads/pose2sim"
    wheel=$(ls "$ROOT/downloads/pose2sim"/*.whl)
    "$PY" - "$wheel" "$ROOT/pose2sim" <<'EOF'
import sys, zipfile, os
wheel, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    for demo, prefix in (("Demo_SinglePerson", ""), ("Demo_MultiPerson", "multi_")):
        for i in range(1, 5):
            name = f"Pose2Sim/{demo}/videos/cam0{i}.mp4"
            tmp = os.path.join(out, f"{prefix}cam0{i}.mp4.tmp")
            with z.open(name) as src, open(tmp, "wb") as dst:
                dst.write(src.read())
            os.replace(tmp, os.path.join(out, f"{prefix}cam0{i}.mp4"))
    tmp = os.path.join(out, "Calib.qca.txt.tmp")
    with z.open("Pose2Sim/Demo_SinglePerson/calibration/Calib.qca.txt") as src, open(tmp, "wb") as dst:
        dst.write(src.read())
    os.replace(tmp, os.path.join(out, "Calib.qca.txt"))
EOF
    rm -rf "$ROOT/downloads/pose2sim"
fi

# --- Derived landmark models: pruned copies, int8 full -------------------------------------------
# Made from the converted models with onnx and ONNX Runtime's own quantisation tools, in a
# private venv removed afterwards. The int8 model is calibrated on the single-person clips above.
# DERIVED names the version of the derivation: models derived by an older one are made again
# (2: pruned models take a batch of crops; 3: they keep the heatmaps, which refine the landmarks;
# 4: only the heatmaps of the landmarks refined, shoulders to feet; 5: copies of the pruned
# models and the detector taking their input channels first, scripts/planar_input.py).
# Files of an older derivation are made again and moved over the old ones, never deleted first:
# rigcast (or its tests) running meanwhile still finds every model it loads.
DERIVED_VERSION=5
stale=0
[[ "$(cat "$ROOT/models/DERIVED" 2>/dev/null)" != "$DERIVED_VERSION" ]] && stale=1
need_derived=$stale
# Whether derived file $1 is there and of this derivation.
fresh() { [[ $stale == 0 && -f "$1" ]]; }
for m in lite full heavy; do
    [[ -f "$ROOT/models/pose_landmark_${m}_pruned.onnx" ]] || need_derived=1
    [[ -f "$ROOT/models/pose_landmark_${m}_planar.onnx" ]] || need_derived=1
done
[[ -f "$ROOT/models/pose_landmark_full_int8.onnx" ]] || need_derived=1
[[ -f "$ROOT/models/pose_detection_planar.onnx" ]] || need_derived=1
if [[ $need_derived == 1 ]]; then
    TOOLS="$ROOT/tools-venv"
    if [[ ! -x "$TOOLS/bin/python" ]] || ! "$TOOLS/bin/python" -c "import onnx, onnxruntime" >/dev/null 2>&1; then
        log "creating model tools venv (onnx $ONNX_VERSION, onnxruntime $ORT_VERSION)"
        "$PY" -m venv "$TOOLS"
        "$TOOLS/bin/python" -m pip install -q "onnx==$ONNX_VERSION" "onnxruntime==$ORT_VERSION" \
            "numpy==$NUMPY_VERSION"
    fi
    for m in lite full heavy; do
        out="$ROOT/models/pose_landmark_${m}_pruned.onnx"
        fresh "$out" && continue
        log "pruning pose_landmark_$m.onnx to the outputs rigcast reads"
        "$TOOLS/bin/python" "$(dirname "$0")/prune_landmark_model.py" \
            "$ROOT/models/pose_landmark_$m.onnx" "$out.tmp.onnx" >&2
        mv "$out.tmp.onnx" "$out"
    done
    for m in landmark_lite landmark_full landmark_heavy detection; do
        src="$ROOT/models/pose_${m}_pruned.onnx"
        [[ $m == detection ]] && src="$ROOT/models/pose_detection.onnx"
        out="$ROOT/models/pose_${m}_planar.onnx"
        fresh "$out" && continue
        log "$(basename "$src"): a copy taking its input channels first"
        "$TOOLS/bin/python" "$(dirname "$0")/planar_input.py" "$src" "$out.tmp.onnx" >&2
        mv "$out.tmp.onnx" "$out"
    done
    out="$ROOT/models/pose_landmark_full_int8.onnx"
    if ! fresh "$out"; then
        log "quantising pose_landmark_full to int8 (calibration on the pose2sim clips, ~1-2 min)"
        "$TOOLS/bin/python" "$(dirname "$0")/quantize_landmark_model.py" \
            "$ROOT/models/pose_landmark_full_pruned.onnx" "$out.tmp.onnx" \
            "$ROOT"/pose2sim/cam0{1,2,3,4}.mp4 >"$ROOT/downloads/quantize_full.log" 2>&1 \
            || { cat "$ROOT/downloads/quantize_full.log" >&2; exit 1; }
        mv "$out.tmp.onnx" "$out"
    fi
    rm -rf "$TOOLS"
fi
echo "$DERIVED_VERSION" >"$ROOT/models/DERIVED"

date -u +%Y-%m-%dT%H:%M:%SZ >"$ROOT/READY"
log "ready in $ROOT"
