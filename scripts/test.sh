#!/usr/bin/env bash
# The test command: install what is missing, then run every test (release build; GPU tests run on
# lavapipe under the Khronos validation layer where it is installed).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --test
# setup.sh may have installed Rust into ~/.cargo without touching the shell profiles.
export PATH="$HOME/.cargo/bin:$PATH"
# lavapipe runs its own worker threads; two test threads keep the 2-core machine from thrashing.
exec cargo test --release -- --test-threads="${RESTIR_VPL_TEST_THREADS:-2}" "$@"
