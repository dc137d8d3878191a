#!/usr/bin/env bash
# On a lent NVIDIA machine (device tool, with `carry: [".dev"]` after scripts/gpu-pack.sh): sets up
# the carried Vulkan loader, validation layer and NVIDIA's ICD, then runs each packed test binary
# with the default number of test threads. A binary still running after HANG_S seconds is taken to
# hang: every thread's stack is written to $OUT/stacks_TEST.txt (eu-stack) and its Rust and Vulkan
# frames printed, then it is killed. Images kept by failing checks come back in artifacts.tar.xz.
# docs/gpu.md ("The test binaries hung") says what such stacks
# showed before.
# Usage: bash scripts/gpu-tests.sh [TEST ...]   (default: every packed one); HANG_S (default 35),
#        THREADS (default: the test harness's), NO_LAYER=1 to run without the validation layer.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/gpu-out}; mkdir -p "$OUT"
HANG_S=${HANG_S:-35}
t0=$(date +%s); el() { echo; echo "[+$(( $(date +%s) - t0 ))s] $*"; }
[ -d .dev/debs ] || { echo "gpu-tests.sh: no .dev/debs: run scripts/gpu-pack.sh here and carry .dev" >&2; exit 2; }
cat .dev/PACKED 2>/dev/null
V=/tmp/gpu-vt; mkdir -p $V; for f in .dev/debs/*.deb; do dpkg -x "$f" $V; done
export LD_LIBRARY_PATH=$V/usr/lib/x86_64-linux-gnu
icd=$(ls /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json /usr/share/vulkan/icd.d/nvidia_icd.json /etc/vulkan/icd.d/nvidia_icd.json 2>/dev/null | head -1)
[ -n "$icd" ] && export VK_DRIVER_FILES=$icd VK_ICD_FILENAMES=$icd
[ "${NO_LAYER:-0}" = 1 ] && export VK_LAYER_PATH=/nonexistent || export VK_LAYER_PATH=$V/usr/share/vulkan/explicit_layer.d
nvidia-smi -L 2>/dev/null
# The test binaries were built at /work/main (CARGO_MANIFEST_DIR) and the CLI tests run
# target/release/restir-vpl there.
mkdir -p target/release && cp .dev/bin/restir-vpl target/release/restir-vpl
if [ "$(readlink -f "$PWD")" != /work/main ]; then mkdir -p /work && ln -sfn "$PWD" /work/main; fi
EU="env LD_LIBRARY_PATH=$V/usr/lib/x86_64-linux-gnu $V/usr/bin/eu-stack"
tests=("$@")
if [ ${#tests[@]} -eq 0 ]; then for f in .dev/tests/*.xz; do tests+=("$(basename "$f" .xz)"); done; fi
mkdir -p /tmp/gpu-tb
summary=()
for t in "${tests[@]}"; do
    xz -dc ".dev/tests/$t.xz" > "/tmp/gpu-tb/$t" && chmod +x "/tmp/gpu-tb/$t" || { summary+=("$t: not packed"); continue; }
    el "$t"
    args=(); [ -n "${THREADS:-}" ] && args=(--test-threads="$THREADS")
    ( cd /work/main && exec setsid env RESTIR_VPL_GPU_TIMEOUT_S=30 RESTIR_VPL_CRASH_STACKS=1 RESTIR_VPL_TEST_ARTIFACTS="$OUT/artifacts" "/tmp/gpu-tb/$t" "${args[@]}" > "$OUT/t_$t.txt" 2>&1 ) & pid=$!
    # stress renders generated scenes in every mode under the layer: 89 s on lavapipe, still
    # running at 40 s on an H100 (stop 42), so it gets at least 150 s.
    limit=$HANG_S; [ "$t" = stress ] && [ "$limit" -lt 150 ] && limit=150
    i=0; while kill -0 $pid 2>/dev/null && [ $i -lt "$limit" ]; do sleep 1; i=$((i+1)); done
    if kill -0 $pid 2>/dev/null; then
        timeout 60 $EU -p $pid > "$OUT/stacks_$t.txt" 2>&1
        echo "HUNG after ${limit} s; stacks in stacks_$t.txt:"
        grep -E "^TID|restir_vpl::|vk[A-Z][A-Za-z]+$|pthread_mutex|_nv004" "$OUT/stacks_$t.txt" | grep -B2 "restir_vpl::vk\|vk[A-Z]" | head -40
        kill -9 -- -$pid 2>/dev/null; summary+=("$t: HUNG")
    else
        wait $pid; rc=$?
        summary+=("$t: rc=$rc, $(grep -E '^test result' "$OUT/t_$t.txt" | tail -1)")
    fi
    # Checks a test skipped (tests/common skip: straight to stderr, past the harness's capture).
    grep -h "SKIPPED" "$OUT/t_$t.txt" | sort -u | head -10
    grep -E "^test .*FAILED$|did not finish" "$OUT/t_$t.txt" | head -10
    grep -A4 "panicked at" "$OUT/t_$t.txt" | head -30
    # A test binary killed by a signal prints the faulting thread's stack first (tests/common).
    grep -A40 "^\*\*\* SIG" "$OUT/t_$t.txt" | grep -E "^\*\*\*|^ +[0-9]+: " | head -40
done
# Images that failing checks kept (tests/common keep_images), in one file: the device tool brings
# back at most 8 files, two folders down.
[ -d "$OUT/artifacts" ] && tar -C "$OUT" -cJf "$OUT/artifacts.tar.xz" artifacts && rm -rf "$OUT/artifacts" && echo "kept images: $OUT/artifacts.tar.xz"
el "summary"; printf '%s\n' "${summary[@]}"
