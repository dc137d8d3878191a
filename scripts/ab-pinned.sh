#!/usr/bin/env bash
# A/B timing of two builds on a machine whose speed drifts (the reference VM moved ±30 % between
# runs, so runs one after the other cannot tell a 10 % change): both binaries run at the same time,
# each on its own core with one lavapipe thread, then again with the cores swapped, so the host's
# drift hits both alike. Prints each pair's lines that match PATTERN and, per matched row, B / A.
# Usage: bash scripts/ab-pinned.sh A B ROUNDS PATTERN -- BENCH ARGS...
#   e.g. cp target/release/restir-vpl /tmp/a; (change, build); cp target/release/restir-vpl /tmp/b
#        bash scripts/ab-pinned.sh /tmp/a /tmp/b 3 '^\| (scenes|generated)' -- bench --photons
# The GPU ms column is the one named by COLUMN (default 6, the photon table's; 3 for `bench`).
set -euo pipefail
A=$1 B=$2 ROUNDS=$3 PATTERN=$4
shift 4
[ "${1:-}" = "--" ] && shift
COLUMN=${COLUMN:-6}
[ "$(nproc)" -ge 2 ] || { echo "ab-pinned.sh: needs 2 cores, this machine has $(nproc)" >&2; exit 1; }
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for round in $(seq 1 "$ROUNDS"); do
  for cores in "0 1" "1 0"; do
    read -r ca cb <<<"$cores"
    LP_NUM_THREADS=1 taskset -c "$ca" "$A" "$@" >"$out/a" 2>&1 & pa=$!
    LP_NUM_THREADS=1 taskset -c "$cb" "$B" "$@" >"$out/b" 2>&1 & pb=$!
    # A failed run leaves no rows, or misaligned pairs: stop with its log's end instead.
    for run in "a $pa $A" "b $pb $B"; do
      read -r which pid bin <<<"$run"
      # (The other run stopped first: the trap removes its output directory.)
      wait "$pid" || { echo "ab-pinned.sh: $bin $* failed:" >&2; tail -5 "$out/$which" >&2; kill "$pa" "$pb" 2>/dev/null; wait 2>/dev/null; exit 1; }
    done
    paste -d'\n' <(grep -E "$PATTERN" "$out/a") <(grep -E "$PATTERN" "$out/b") |
      awk -F'|' -v col="$COLUMN" -v r="$round" -v ca="$ca" -v cb="$cb" '
        NR % 2 == 1 { a = $col; name = $2; next }
        { printf "round %s (A on cpu %s, B on cpu %s) %-40s A %8.1f  B %8.1f  B/A %.3f\n", r, ca, cb, name, a, $col, $col / a }'
  done
done
