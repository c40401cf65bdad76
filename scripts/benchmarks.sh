#!/usr/bin/env bash
# Regenerate docs/BENCHMARKS.md (tables, plots in docs/img, CSV/JSON in docs/bench):
# builds the release binary, then runs the whole suite with `plume bench report`.
# About 10 minutes of wall time on 2 cores; budgets are CPU seconds, so other load on the
# machine slows the run down but changes the figures much less. Extra arguments go to
# `plume bench report` (e.g. `--time-scale 0.1` for a quick look, `-o /tmp/bench`).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo build --release
exec target/release/plume bench report "$@"
