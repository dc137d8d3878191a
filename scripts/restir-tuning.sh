#!/usr/bin/env bash
# ReSTIR's cost against its error as the initial candidates and spatial neighbours change, on the
# three scenes (about 256 px wide, 100k + 100k VPLs, unbiased defaults otherwise): GPU ms per frame
# and RMSE against a path-traced reference after 1 frame (what a moving camera shows) and after 20
# accumulated frames, plus uniform sampling's GPU ms for the ratio. Runs are sequential: GPU ms
# drift on a shared machine, compare within one table. Usage: bash scripts/restir-tuning.sh [REF_FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
REF_FRAMES=${1:-512}
cargo build --release -q
BIN=${CARGO_TARGET_DIR:-target}/release/restir-vpl
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
printf '| scene | candidates | neighbours | GPU ms / frame | × uniform | RMSE t=1 | RMSE t=20 |\n|---|---:|---:|---:|---:|---:|---:|\n'
for spec in cornell_box:256:256 living_room:256:144 open_box_figure:256:144; do
  IFS=: read -r name w h <<<"$spec"
  COMMON=(--headless --scene "scenes/$name.gltf" --width "$w" --height "$h")
  "$BIN" "${COMMON[@]}" --mode pt --frames "$REF_FRAMES" --seed 1000 --out "$OUT/$name-ref" >/dev/null 2>&1
  "$BIN" "${COMMON[@]}" --mode uniform --frames 20 --out "$OUT/$name-uniform" >/dev/null 2>&1
  for c in 4 8 16 32; do
    for n in 2 4 8; do
      D="$OUT/$name-c$c-n$n"
      "$BIN" "${COMMON[@]}" --mode restir --candidates "$c" --spatial-neighbours "$n" --frames 20 --save-every 1 --out "$D" >/dev/null 2>&1
      "$BIN" compare "$D/accum_0001.exr" "$OUT/$name-ref/final.exr" --json "$D/t1.json" >/dev/null
      "$BIN" compare "$D/final.exr" "$OUT/$name-ref/final.exr" --json "$D/t20.json" >/dev/null
      python3 - "$D" "$OUT/$name-uniform" "$name" "$c" "$n" <<'PY'
import json, sys
d, u, name, c, n = sys.argv[1:6]
s = json.load(open(f"{d}/summary.json")); us = json.load(open(f"{u}/summary.json"))
t1 = json.load(open(f"{d}/t1.json"))["comparison"]; t20 = json.load(open(f"{d}/t20.json"))["comparison"]
ms = s["gpu_ms_per_frame"]["median"]; ums = us["gpu_ms_per_frame"]["median"]
print(f"| {name} | {c} | {n} | {ms:.1f} | {ms / ums:.2f} | {t1['rmse']:.4f} | {t20['rmse']:.4f} |")
PY
    done
  done
done
