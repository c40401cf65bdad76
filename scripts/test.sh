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
# Debian's slurm-wlm and munge for tests/batch_slurm.rs, which starts a one-node cluster of its own
# (its daemons in a scratch directory, on free loopback ports) and stops it. Without them
# that test is skipped with a loud message.
slurm_pkgs=()
for pkg in slurm-wlm munge; do
    dpkg -s "$pkg" >/dev/null 2>&1 || slurm_pkgs+=("$pkg")
done
if [ ${#slurm_pkgs[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    if ! { $SUDO apt-get update -qq &&
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${slurm_pkgs[@]}"; }; then
        echo "test.sh: WARNING: cannot install ${slurm_pkgs[*]}; the Slurm test will be SKIPPED" >&2
    fi
fi
# The Slurm test's daemons never outlive the run: any left (a killed test process) are
# reported and stopped, and the run fails.
slurm_leftovers() {
    local pids
    pids=$(pgrep -f 'plume-slurm-cluster-' || true)
    [ -z "$pids" ] && return 0
    echo "test.sh: ERROR: Slurm daemons outlived the tests:" >&2
    ps -o pid=,args= -p "${pids//$'\n'/,}" >&2 || true
    # shellcheck disable=SC2086
    kill -9 $pids 2>/dev/null || true
    return 1
}
trap 'status=$?; slurm_leftovers || status=1; exit $status' EXIT
bash scripts/check-quiet.sh  # the library never prints, exits or reads the environment (file:line)
# Style gates first (cheap, and a failure says exactly where): formatting per rustfmt.toml,
# and clippy with every warning an error.
if ! cargo fmt --version >/dev/null 2>&1 || ! cargo clippy --version >/dev/null 2>&1; then
    command -v rustup >/dev/null 2>&1 && rustup component add rustfmt clippy
fi
cargo fmt --all --check
cargo clippy --workspace --all-targets -- -D warnings
# One test thread more than the cores: the Slurm test holds a thread for about 90 s while
# it mostly waits for Slurm's time limit.
export RUST_TEST_THREADS="${RUST_TEST_THREADS:-$(( $(nproc) + 1 ))}"
cargo test --workspace --all-targets --no-fail-fast "$@"
# The Python package (python/): built by maturin with the dev profile in this target
# directory (reusing what the tests compiled), installed into a venv under target/, and
# tested by pytest against the plume binary just built. Skipped when cargo test was given
# a filter that names no Python test.
if [ $# -eq 0 ] || [[ "$*" == *python* ]]; then
    target="${CARGO_TARGET_DIR:-target}"
    pyvenv="$target/python-venv"
    if [ ! -x "$pyvenv/bin/maturin" ]; then
        python3 -m venv "$pyvenv"
        "$pyvenv/bin/python" -m pip install --quiet "maturin>=1.9,<2" "numpy>=1.21" "pytest>=7"
    fi
    rm -rf "$target/python-wheels"
    "$pyvenv/bin/maturin" build --profile dev --quiet --manifest-path python/Cargo.toml -o "$target/python-wheels"
    "$pyvenv/bin/python" -m pip install --quiet --force-reinstall --no-deps "$target"/python-wheels/plume-*.whl
    PLUME_BIN="$target/debug/plume" "$pyvenv/bin/python" -m pytest -q python/tests
fi
