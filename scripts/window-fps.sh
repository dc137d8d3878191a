#!/usr/bin/env bash
# Windowed frame rate of each mode against headless, same scene, size and frame count: the
# README's "present overhead" table. Runs the window under its own Xvfb when no DISPLAY is set
# (bash scripts/setup.sh --test installs Xvfb). Usage: bash scripts/window-fps.sh [W H FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-1280}; H=${2:-720}; FRAMES=${3:-12}
cargo build --release -q
BIN=target/release/restir-vpl
OUT=$(mktemp -d)
XPID=""
if [ -z "${DISPLAY:-}" ]; then
  export DISPLAY=:87
  Xvfb "$DISPLAY" -screen 0 "$((W + 64))x$((H + 64))x24" -nolisten tcp -noreset >/dev/null 2>&1 &
  XPID=$!
  sleep 2
fi
trap '[ -n "$XPID" ] && kill "$XPID"; rm -rf "$OUT"' EXIT
SCENE=(--scene scenes/cornell_box.gltf --width "$W" --height "$H" --frames "$FRAMES")
printf '| mode | window ms / displayed frame | window fps | headless ms / frame | window / headless | GPU ms / frame (window) |\n|---|---:|---:|---:|---:|---:|\n'
for mode in uniform ris restir pt; do
  # Interleaved, window first then headless, so drift on a shared machine hits both alike.
  "$BIN" "${SCENE[@]}" --mode "$mode" --out "$OUT/win_$mode" >/dev/null 2>&1
  "$BIN" --headless "${SCENE[@]}" --mode "$mode" --out "$OUT/head_$mode" >/dev/null 2>&1
  python3 - "$OUT/win_$mode/summary.json" "$OUT/head_$mode/summary.json" "$mode" <<'PY'
import json, sys
w = json.load(open(sys.argv[1])); h = json.load(open(sys.argv[2]))
d = w["displayed"]; hw = h["wall_ms_per_frame"]["median"]
print(f"| {sys.argv[3]} | {d['ms_per_frame']:.1f} | {d['fps']:.2f} | {hw:.1f} | {d['ms_per_frame'] / hw:.2f} | {w['gpu_ms_per_frame']['median']:.1f} |")
PY
done
