#!/usr/bin/env bash
# The README's test command: installs what it needs, builds, and runs every test.
# Usage: scripts/test.sh [--sanitize]   (extra arguments go to scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
dir=$(bash scripts/build.sh "$@" | tail -n 1)
if [[ " $* " == *" --sanitize "* ]]; then
  # OpenMP's runtime keeps thread-pool memory until exit; it is not a leak of ours.
  export ASAN_OPTIONS=detect_leaks=0:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
fi
# ctest runs one test process per core. Each process defaults to one OpenMP thread: results are
# bitwise identical for any thread count (tests/*/determinism checks prove it), the tests that
# exercise two threads set it themselves, and oversubscribed spinning barriers would otherwise
# cost more than they gain.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
ctest --test-dir "$dir" --output-on-failure -j"$(nproc)" --timeout 300
