#!/usr/bin/env bash
# The main job: build plume, generate the sample explosion, render it to EXR + PNG.
# Outputs: out/explosion.vdb, out/explosion.exr, out/explosion.png, out/explosion.json
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo build --release
mkdir -p out
./target/release/plume synth explosion --resolution 128 --seed 1 -o out/explosion.vdb
# The shot is the sample scene file (640×480, 32 spp, scattering, denoised; its comments
# say why each key), so `plume bench demo` times and judges exactly what this renders
./target/release/plume render data/explosion.toml "$@"
echo "wrote out/explosion.exr and out/explosion.png"
