#!/usr/bin/env bash
# Prepares the independent VMC receiver the end-to-end tests judge rigcast's VMC output with:
# a private Python venv holding python-osc (PyPI), an OSC decoder rigcast shares no code with.
#
#   $RIGCAST_HOME/vmc-check/venv/bin/python   (RIGCAST_HOME defaults to ~/.cache/rigcast)
#
# Idempotent: skipped when the venv already imports pythonosc. Set RIGCAST_SKIP_APPS=1 to skip
# (the tests that need it then skip too, with a printed reason).
set -euo pipefail

PYTHON_OSC_VERSION="1.10.2"
ROOT="${RIGCAST_HOME:-$HOME/.cache/rigcast}/vmc-check"
VENV="$ROOT/venv"

[[ "${RIGCAST_SKIP_APPS:-0}" == "1" ]] && { echo "setup-vmc-check: RIGCAST_SKIP_APPS=1, skipping"; exit 0; }
"$VENV/bin/python" -c "import pythonosc" >/dev/null 2>&1 && exit 0
echo "setup-vmc-check: creating $VENV with python-osc $PYTHON_OSC_VERSION" >&2
mkdir -p "$ROOT"
python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install -q "python-osc==$PYTHON_OSC_VERSION"
"$VENV/bin/python" -c "import pythonosc"
