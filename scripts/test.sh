#!/usr/bin/env bash
# The whole test suite: installs dependencies, then runs every test.
# Real-data tests read ../shared/data (beside the checkout).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo test --all-targets --no-fail-fast "$@"
