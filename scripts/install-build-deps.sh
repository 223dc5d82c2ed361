#!/usr/bin/env bash
# Installs what building rigcast needs beyond Rust, on Debian/Ubuntu:
#   libclang-dev  — nokhwa's V4L2 bindings (the webcam source) run bindgen at build time
#   nasm          — lets mozjpeg (the camera's MJPEG decoder) build its SIMD code
#   gcc           — the C compiler both use (and the emulated camera of the tests)
# Idempotent: does nothing when all are present. Without root it uses sudo.
# A build without webcam support needs none of this: `cargo build --no-default-features`.
set -euo pipefail

need=()
for pkg in libclang-dev nasm gcc; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [[ ${#need[@]} -eq 0 ]]; then
    echo "install-build-deps: libclang-dev, nasm and gcc already installed"
    exit 0
fi

SUDO=""
if [[ "$(id -u)" != "0" ]]; then
    SUDO="sudo"
fi
echo "install-build-deps: installing ${need[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"
