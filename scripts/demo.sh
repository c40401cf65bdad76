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
./target/release/plume render out/explosion.vdb -o out/explosion.exr --preview out/explosion.png \
    --stats out/explosion.json --spp 32 --width 640 --height 480 --density-scale 4 --albedo 0.8 --g 0.3 --split 6 --split-by brightness --camera-estimator ray-march --denoise "$@"
echo "wrote out/explosion.exr and out/explosion.png"
