#!/usr/bin/env bash
# The whole test suite: installs dependencies, then runs every test.
# Real-data tests read ../shared/data (beside the checkout).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
# openjd-cli (PyPI) for the Open Job Description test in tests/farm.rs, installed the way a
# user would, into a venv under target/. Without it that test skips with a loud message.
venv="${CARGO_TARGET_DIR:-target}/openjd-venv"
if [ ! -x "$venv/bin/openjd" ]; then
    if ! { python3 -m venv "$venv" && "$venv/bin/python" -m pip install --quiet openjd-cli; }; then
        echo "test.sh: WARNING: cannot install openjd-cli into $venv; the OpenJD test will be SKIPPED" >&2
    fi
fi
bash scripts/check-quiet.sh  # the library never prints, exits or reads the environment (file:line)
# Style gates first (cheap, and a failure says exactly where): formatting per rustfmt.toml,
# and clippy with every warning an error.
if ! cargo fmt --version >/dev/null 2>&1 || ! cargo clippy --version >/dev/null 2>&1; then
    command -v rustup >/dev/null 2>&1 && rustup component add rustfmt clippy
fi
cargo fmt --all --check
cargo clippy --workspace --all-targets -- -D warnings
cargo test --workspace --all-targets --no-fail-fast "$@"
