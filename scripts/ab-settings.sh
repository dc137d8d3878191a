#!/usr/bin/env bash
# A/B timing of two settings of one build, as scripts/ab-pinned.sh does for two builds: both runs
# at the same time, each on its own core with one lavapipe thread, then again with the cores
# swapped, so the host's drift hits both alike. Each run is a headless render of SCENE along its
# committed camera path (every frame displayed alone, as while flying) at 1280×720 with 100k + 100k
# VPLs; prints per pair the median GPU ms of the frame and of the ReSTIR passes, and B / A.
# Usage: bash scripts/ab-settings.sh SCENE ROUNDS "A FLAGS" "B FLAGS" [BINARY]
#   e.g. bash scripts/ab-settings.sh cornell_box 2 "--mode restir --moving-candidates 16" "--mode restir --moving-candidates 8"
set -euo pipefail
SCENE=$1 ROUNDS=$2 A=$3 B=$4
BIN=${5:-${CARGO_TARGET_DIR:-target}/release/restir-vpl}
[ "$(nproc)" -ge 2 ] || { echo "ab-settings.sh: needs 2 cores, this machine has $(nproc)" >&2; exit 1; }
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() { # core flags dir
  # shellcheck disable=SC2086
  LP_NUM_THREADS=1 taskset -c "$1" "$BIN" --headless $2 --scene "scenes/$SCENE.gltf" --camera-path "scenes/$SCENE.path.json" \
    --width 1280 --height 720 --frames 8 --vpls-direct 100000 --vpls-indirect 100000 --out "$3" >"$3.log" 2>&1 ||
    { echo "ab-settings.sh: the run with '$2' failed:" >&2; tail -5 "$3.log" >&2; exit 1; }
}
medians() { # summary.json -> "frame pass=ms ..."
  python3 -c "
import json, sys
d = json.load(open(sys.argv[1])); p = d['pass_ms']
print('%.1f' % d['gpu_ms_per_frame']['median'], ' '.join('%s=%.1f' % (k, p[k]['median']) for k in sorted(p) if k.startswith('restir_')))" "$1"
}
for round in $(seq 1 "$ROUNDS"); do
  for cores in "0 1" "1 0"; do
    read -r ca cb <<<"$cores"
    run "$ca" "$A" "$out/a" & pa=$!
    run "$cb" "$B" "$out/b" & pb=$!
    # (wait on both apart: `wait A B` returns B's status only; a failed A would leave the previous
    # round's summary to be read as this round's.)
    wait "$pa" || { kill "$pb" 2>/dev/null; wait "$pb" 2>/dev/null; exit 1; }
    wait "$pb" || exit 1
    a=$(medians "$out/a/summary.json") b=$(medians "$out/b/summary.json")
    python3 -c "import sys; a, b = sys.argv[1], sys.argv[2]; print('round $round (A on cpu $ca, B on cpu $cb): A %s | B %s | frame B/A %.3f' % (a, b, float(b.split()[0]) / float(a.split()[0])))" "$a" "$b"
  done
done
