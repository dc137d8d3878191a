#!/usr/bin/env bash
# Installs what restir-vpl needs on a Debian/Ubuntu machine, and only what is missing:
#   - a Vulkan loader (libvulkan1)
#   - a Vulkan driver with VK_KHR_ray_query (Mesa >= 24.1 lavapipe from bookworm-backports on
#     Debian 12, only when no such driver is present)
#   - the Khronos validation layer (vulkan-validationlayers)
#   - a C/C++ compiler for the glslang crate's build
#   - Rust (stable, through rustup) when no toolchain as new as Cargo.toml's rust-version is found
# With --test (the test command) also what the tests drive: Xvfb, xdotool and xmessage for the window tests,
# headless Chromium for the pass inspector page (the main job never pulls a browser).
# The main job does not pull these.
# Idempotent and quiet when everything is there. Set RESTIR_VPL_SKIP_SETUP=1 to skip it entirely.
set -euo pipefail

for_tests=0
[ "${1:-}" = "--test" ] && for_tests=1

[ "${RESTIR_VPL_SKIP_SETUP:-0}" = 1 ] && exit 0

log() { echo "[setup] $*" >&2; }
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
need_sudo() {
  # Called before the first install: a user without sudo got "sudo: command not found" (127).
  if [ -n "$SUDO" ] && ! command -v sudo >/dev/null 2>&1; then
    log "installing packages needs root: run this script as root, or install sudo"
    exit 1
  fi
}

have_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "ok installed"; }

apt_updated=0
apt_install() {
  # apt_install [apt-get options...] pkgs...
  need_sudo
  if [ "$apt_updated" = 0 ]; then
    log "apt-get update"
    $SUDO apt-get update -qq >/dev/null || { sleep 3; $SUDO apt-get update -qq >/dev/null; }
    apt_updated=1
  fi
  log "apt-get install $*"
  # A first install sometimes fails with "cannot access archive"; retry once.
  # (env inside sudo: sudo's env_reset drops a variable set before it.)
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null \
    || { sleep 3; $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null; }
}

if ! command -v dpkg-query >/dev/null 2>&1; then
  log "not a Debian/Ubuntu system: install a Vulkan 1.2+ driver with VK_KHR_ray_query, the Vulkan loader,"
  log "the Khronos validation layer and a C++ compiler yourself, then set RESTIR_VPL_SKIP_SETUP=1"
  exit 0
fi

# Build tools (the glslang crate compiles glslang's C++ sources).
missing=()
command -v cc >/dev/null 2>&1 || missing+=(gcc)
command -v c++ >/dev/null 2>&1 || missing+=(g++)
command -v pkg-config >/dev/null 2>&1 || missing+=(pkg-config)
have_pkg libvulkan1 || missing+=(libvulkan1)
have_pkg vulkan-validationlayers || missing+=(vulkan-validationlayers)
if [ "$for_tests" = 1 ]; then
  # The window tests: an X server, a way to press keys, and the libraries winit loads.
  command -v Xvfb >/dev/null 2>&1 || missing+=(xvfb)
  command -v xdotool >/dev/null 2>&1 || missing+=(xdotool)
  command -v xmessage >/dev/null 2>&1 || missing+=(x11-utils) # a window that covers the renderer's
  command -v chromium >/dev/null 2>&1 || missing+=(chromium)
  for lib in libxkbcommon-x11-0 libxcursor1 libxi6 libx11-xcb1; do have_pkg "$lib" || missing+=("$lib"); done
fi
if [ ${#missing[@]} -gt 0 ]; then apt_install "${missing[@]}"; fi

# A driver with ray queries. A vendor driver (NVIDIA/AMD/Intel ICD) is left alone; for Mesa we need
# >= 24.1 (lavapipe's ray queries). Debian 12 ships 22.3: take mesa-vulkan-drivers from backports.
vendor_icd=0
for f in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json; do
  [ -e "$f" ] || continue
  case "$(basename "$f")" in
    lvp_*|radeon_*|intel_*|nouveau_*|virtio_*|freedreno_*|broadcom_*|asahi_*|powervr_*|panfrost_*|gfxstream_*|dzn_*) ;;
    *) vendor_icd=1 ;;
  esac
done
mesa_ver=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
mesa_ok=0
if [ -n "$mesa_ver" ] && dpkg --compare-versions "$mesa_ver" ge 24.1; then mesa_ok=1; fi
if [ "$mesa_ok" = 0 ] && [ "$vendor_icd" = 0 ]; then
  . /etc/os-release
  if [ "${VERSION_CODENAME:-}" = bookworm ]; then
    # (A commented-out line does not count: apt would not know the release.)
    if ! grep -rqsE '^[^#]*bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d/; then
      log "adding bookworm-backports (for Mesa >= 24.1 with VK_KHR_ray_query)"
      need_sudo
      echo 'deb http://deb.debian.org/debian bookworm-backports main' | $SUDO tee /etc/apt/sources.list.d/backports.list >/dev/null
      apt_updated=0
    fi
    apt_install -t bookworm-backports mesa-vulkan-drivers
  else
    apt_install mesa-vulkan-drivers
    mesa_ver=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
    if ! dpkg --compare-versions "$mesa_ver" ge 24.1; then
      log "warning: mesa-vulkan-drivers $mesa_ver has no VK_KHR_ray_query in lavapipe (needs Mesa >= 24.1)"
    fi
  fi
fi

# Rust toolchain: the one on PATH or in ~/.cargo/bin when it is new enough for Cargo.toml's
# rust-version, else a stable toolchain through rustup (into ~/.cargo, without touching shell
# profiles; the scripts put ~/.cargo/bin on PATH themselves). Debian's own rustc is too old.
need_rust=$(sed -n 's/^rust-version *= *"\([0-9.]*\)".*/\1/p' "$(dirname "$0")/../Cargo.toml")
export PATH="$HOME/.cargo/bin:$PATH"
rust_ok() {
  command -v cargo >/dev/null 2>&1 && command -v rustc >/dev/null 2>&1 || return 1
  local have
  have=$(rustc --version | awk '{print $2}')
  dpkg --compare-versions "${have%%-*}" ge "${need_rust:-0}"
}
if ! rust_ok; then
  if command -v rustup >/dev/null 2>&1; then
    log "rustc older than $need_rust: rustup toolchain install stable"
    { rustup toolchain install stable --profile minimal >/dev/null && rustup default stable >/dev/null; } \
      || log "rustup could not install the stable toolchain (above)"
  else
    for p in curl ca-certificates; do have_pkg "$p" || apt_install "$p"; done
    log "installing Rust (stable, minimal profile) through rustup into ~/.cargo"
    curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs \
      | sh -s -- -y --profile minimal --default-toolchain stable --no-modify-path >/dev/null \
      || log "rustup's installer failed (above)"
  fi
  rust_ok || { log "could not get a Rust toolchain >= $need_rust (https://rustup.rs): install one and re-run"; exit 1; }
fi
exit 0
