#!/usr/bin/env bash
# Prepares Blender-as-a-Python-module for the add-on test matrix: one private venv per Blender
# version, each holding the official `bpy` wheel from PyPI (CPython 3.11 wheels exist for the
# 4.2 LTS, 4.5 LTS and 5.0 series). 4.2 is the first with the extensions platform and still
# has only legacy Actions; 4.5 has layered Actions beside the old API; 5.0 only layered ones.
#
#   $RIGCAST_HOME/bpy/<series>/venv/bin/python   (RIGCAST_HOME defaults to ~/.cache/rigcast)
#
# Idempotent: a venv that already imports bpy is left alone, so runs after the first cost
# nothing. A version whose wheel cannot be installed (no wheel for this Python, no network) is
# reported and skipped; the test matrix then skips that version with the reason printed here
# (kept in <series>/failed). Set RIGCAST_SKIP_APPS=1 to skip entirely.
set -uo pipefail

if [[ "${RIGCAST_SKIP_APPS:-0}" == "1" ]]; then
    echo "setup-bpy: RIGCAST_SKIP_APPS=1, skipping"
    exit 0
fi

# series → exact pinned release (pinned so every run tests the same Blender).
VERSIONS=("4.2=4.2.23" "4.5=4.5.15" "5.0=5.0.1")
ROOT="${RIGCAST_HOME:-$HOME/.cache/rigcast}/bpy"
PYTHON="${RIGCAST_BPY_PYTHON:-python3}"

for entry in "${VERSIONS[@]}"; do
    series="${entry%%=*}"
    version="${entry#*=}"
    dir="$ROOT/$series"
    venv="$dir/venv"
    if "$venv/bin/python" -c "import bpy, sys; sys.exit(0 if bpy.app.version_string.startswith('$version') else 1)" >/dev/null 2>&1; then
        continue
    fi
    echo "setup-bpy: installing bpy==$version into $venv (a few hundred MB, once)" >&2
    rm -rf "$dir"
    mkdir -p "$dir"
    log="$dir/install.log"
    if "$PYTHON" -m venv "$venv" >"$log" 2>&1 \
        && "$venv/bin/python" -m pip install -q --disable-pip-version-check "bpy==$version" >>"$log" 2>&1 \
        && "$venv/bin/python" -c "import bpy" >>"$log" 2>&1; then
        rm -f "$dir/failed"
        echo "setup-bpy: bpy $version ready" >&2
    else
        # Keep the reason for the test to print; do not fail the whole test command.
        { echo "bpy==$version could not be installed with $("$PYTHON" --version 2>&1):"; tail -n 5 "$log"; } >"$dir/failed"
        rm -rf "$venv"
        echo "setup-bpy: bpy $version unavailable (see $dir/failed)" >&2
    fi
done
exit 0
