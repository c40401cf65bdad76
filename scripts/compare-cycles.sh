#!/usr/bin/env bash
# Peer comparison with Blender Cycles 5.0.1: renders the shared Blender explosions in plume
# and in Cycles with matched conventions, measures each renderer's relRMSE against its own
# converged reference at several CPU budgets, and prints a Markdown table (also written to
# target/compare-cycles/table.md with the raw JSON).
#
# A benchmark, not a test: it installs bpy==5.0.1 (PyPI, Python 3.11) into a venv under
# target/, builds plume in release, and takes hours for the full set on 2 cores (the
# references dominate). `--quick` runs one file, two settings and short references to
# check the set-up in minutes. Other options: see `scripts/compare_cycles.py --help`.
#
#   bash scripts/compare-cycles.sh            # full table
#   bash scripts/compare-cycles.sh --quick    # a quick look
#   bash scripts/compare-cycles.sh --lights   # sun, environment map and sphere light
#                                             # (scripts/compare_lights.py)
#   bash scripts/compare-cycles.sh --shots    # a coloured medium, depth of field
#                                             # (scripts/compare_shots.py)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo build --release
venv="${CARGO_TARGET_DIR:-target}/bpy-venv"
python=python3.11
command -v "$python" >/dev/null 2>&1 || python=python3
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import bpy, OpenEXR" >/dev/null 2>&1; then
    "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet "bpy==5.0.1" "OpenEXR>=3.2"
fi
if [ "${1:-}" = "--lights" ]; then
    shift
    exec "$venv/bin/python" scripts/compare_lights.py --plume "${CARGO_TARGET_DIR:-target}/release/plume" "$@"
fi
if [ "${1:-}" = "--shots" ]; then
    shift
    exec "$venv/bin/python" scripts/compare_shots.py --plume "${CARGO_TARGET_DIR:-target}/release/plume" "$@"
fi
exec "$venv/bin/python" scripts/compare_cycles.py --plume "${CARGO_TARGET_DIR:-target}/release/plume" "$@"
