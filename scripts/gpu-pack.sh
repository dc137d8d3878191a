#!/usr/bin/env bash
# Packs what a lent GPU machine needs to run this project's binaries and test binaries, into .dev/
# (ignored by git; pass `carry: [".dev"]` to the device tool). The lent machines so far (H100, H200:
# Ubuntu 24.04, NVIDIA's driver and ICD, no Vulkan loader, no validation layer, no debugger) got:
#   .dev/debs/     Debian 12's Vulkan loader, validation layer, vulkaninfo (and their X11 libraries),
#                  elfutils' eu-stack, to take every thread's stack of a hung process, and libglvnd
#                  (the H100 image of stop 42 had none, and NVIDIA's ICD then failed to load:
#                  libnvidia-glcore's symbol lookups fail, the loader finds no driver)
#   .dev/bin/      restir-vpl, stripped
#   .dev/tests/    the chosen test binaries, with their symbol tables (for eu-stack) but no debug
#                  info, xz-compressed
# Then, on the device: bash scripts/gpu-tests.sh [TEST ...] (see there). The test binaries look
# for scenes at this checkout's path (CARGO_MANIFEST_DIR), which gpu-tests.sh links to.
# Usage: bash scripts/gpu-pack.sh [TEST ...]   (default: headless furnace photons vpl_modes)
set -euo pipefail
cd "$(dirname "$0")/.."
tests=("$@")
[ ${#tests[@]} -gt 0 ] || tests=(headless furnace photons vpl_modes)
cargo build --release --all-targets
rm -rf .dev/debs .dev/bin .dev/tests
mkdir -p .dev/debs .dev/bin .dev/tests
debs=(libvulkan1 vulkan-validationlayers vulkan-tools libx11-6 libxcb1 libxau6 libxdmcp6 libbsd0 libmd0
    libwayland-client0 elfutils libdw1 libelf1 libglvnd0 libglx0 libgl1 libegl1 libopengl0 libgles2)
# A package that fails to download here would only show on the lent machine, in its scarce time:
# stop now, naming it. (apt's warning about unsandboxed downloads as root is noise.)
(cd .dev/debs && apt-get download -q "${debs[@]}" 2>&1 | grep -v "^W: Download is performed unsandboxed" || true)
for d in "${debs[@]}"; do
    compgen -G ".dev/debs/${d}_*.deb" >/dev/null || { echo "gpu-pack.sh: apt-get download $d failed" >&2; exit 2; }
done
strip -o .dev/bin/restir-vpl target/release/restir-vpl
for t in "${tests[@]}"; do
    bin=$(ls -t target/release/deps/"$t"-* 2>/dev/null | grep -v '\.d$' | head -1 || true)
    [ -n "$bin" ] || { echo "gpu-pack.sh: no test binary named $t in target/release/deps" >&2; exit 2; }
    strip --strip-debug -o ".dev/tests/$t" "$bin"
    xz -T0 -3 -f ".dev/tests/$t"
done
# The repository copy the device tool makes sends untracked, unignored files as well: make sure
# .dev is ignored here, so it travels only when carried.
git check-ignore -q .dev || { echo "gpu-pack.sh: .dev is not ignored by git" >&2; exit 2; }
du -sh .dev/debs .dev/bin .dev/tests
echo "commit $(git rev-parse --short HEAD)$(git diff --quiet || echo ' (with uncommitted changes)')" > .dev/PACKED
cat .dev/PACKED
