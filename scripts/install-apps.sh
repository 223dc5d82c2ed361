#!/usr/bin/env bash
# Installs the real programs the end-to-end tests drive: Blender (add-on test), Chromium (web
# viewer test) and nats-server (cluster test). Idempotent: does nothing when all are already
# present, so the test command can call it every time. Set RIGCAST_SKIP_APPS=1 to skip installing entirely.
set -euo pipefail

if [[ "${RIGCAST_SKIP_APPS:-0}" == "1" ]]; then
    echo "install-apps: RIGCAST_SKIP_APPS=1, not installing blender/chromium/nats-server"
    exit 0
fi

need=()
command -v blender >/dev/null 2>&1 || need+=(blender)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
# Debian puts nats-server in /usr/sbin, which is not on every user's PATH.
command -v nats-server >/dev/null 2>&1 || [[ -x /usr/sbin/nats-server ]] || need+=(nats-server)
# Blender's bundled Python imports numpy at startup on Debian.
dpkg -s python3-numpy >/dev/null 2>&1 || need+=(python3-numpy)
# The Python venvs of the test setup (setup-vmc-check.sh, setup-bpy.sh) need Debian's venv module.
dpkg -s python3-venv >/dev/null 2>&1 || need+=(python3-venv)
# Headless Blender and Chromium want these fonts for UI text and the screenshot's labels.
dpkg -s fonts-dejavu-core >/dev/null 2>&1 || need+=(fonts-dejavu-core)

if [[ ${#need[@]} -eq 0 ]]; then
    echo "install-apps: blender, chromium and nats-server already installed"
    exit 0
fi

SUDO=""
if [[ "$(id -u)" != "0" ]]; then
    SUDO="sudo"
fi
echo "install-apps: installing ${need[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"
