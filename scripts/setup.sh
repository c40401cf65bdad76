#!/usr/bin/env bash
# Install what plume needs to build on Debian: OpenVDB 10 (+ Boost headers, which its
# headers need but the package does not pull in) and a C++ compiler; python3-venv for the
# openjd-cli the farm tests install and the Python package's tests; python3-dev, whose
# libpython the Python extension (python/) links when the workspace is built. Idempotent: does nothing when everything is present.
set -euo pipefail
need=()
for pkg in libopenvdb-dev libboost-dev g++ pkg-config python3-venv python3-dev; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
    echo "setup: installing ${need[*]}" >&2
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${need[@]}"
fi
if ! command -v cargo >/dev/null 2>&1; then
    [ -x "$HOME/.cargo/bin/cargo" ] && export PATH="$HOME/.cargo/bin:$PATH"
fi
command -v cargo >/dev/null 2>&1 || { echo "setup: cargo not found; install a Rust toolchain (1.83 or newer)" >&2; exit 1; }
