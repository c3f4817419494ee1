#!/usr/bin/env bash
# Configures and builds Streetlight. Usage: scripts/build.sh [--sanitize] [--debug] [--dir DIR]
#   default: Release (-O3 -march=native) in build/
#   --sanitize: AddressSanitizer + UndefinedBehaviorSanitizer (RelWithDebInfo) in build-asan/
#   --debug:    Debug in build-debug/
set -euo pipefail
cd "$(dirname "$0")/.."
build_type=Release; dir=build; extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --sanitize) build_type=RelWithDebInfo; dir=build-asan; extra+=(-DSTREETLIGHT_SANITIZE=ON) ;;
    --debug) build_type=Debug; dir=build-debug ;;
    --dir) dir="$2"; shift ;;
    -h|--help) sed -n '2,6p' "$0"; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE="$build_type" "${extra[@]}" > "$dir.configure.log" 2>&1 \
  || { cat "$dir.configure.log" >&2; exit 1; }
cmake --build "$dir" -j"$(nproc)"
echo "$dir"
