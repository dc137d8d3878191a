#!/usr/bin/env bash
# The main job: install what is missing, build, render the bundled Cornell box headless and print
# where the images are and the GPU milliseconds per pass. Extra arguments go to restir-vpl.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# setup.sh may have installed Rust into ~/.cargo without touching the shell profiles.
export PATH="$HOME/.cargo/bin:$PATH"
# (cargo run finds the binary wherever CARGO_TARGET_DIR or a cargo config puts it: a path to
# ./target/release failed under CARGO_TARGET_DIR.)
exec cargo run --release --quiet -- --headless --scene scenes/cornell_box.gltf --mode restir \
  --frames 20 --width 512 --height 512 --out out/cornell "$@"
