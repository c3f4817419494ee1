#!/usr/bin/env bash
# Runs the kernel test suites on the SIMD paths that -march=native does not pick, so that every path
# this CPU can run is tested, not only its widest (issue 38). Usage:
#   scripts/test_simd_paths.sh [--all] [--paths avx2,scalar]
# The convolution micro-kernels, Winograd and the BVH choose AVX-512, AVX2 + FMA or scalar code at
# compile time (CMake's STREETLIGHT_ARCH, util/compiled_isa.h). The README's test command builds and
# tests the native (widest) path; this script builds each other path into build-simd-<path>/
# (x86-64-v3 for avx2, x86-64-v2 for scalar) and runs util, autodiff, nn and render tests there, with
# STREETLIGHT_SIMD lowered to the same level for the run-time dispatched functions
# (autodiff/vector_math.h). --all builds and runs the whole suite instead. A path this CPU cannot
# run is skipped with a message. Each build's CompiledIsa test checks that it compiled the path it
# was asked for.
set -euo pipefail
cd "$(dirname "$0")/.."
paths="avx2,scalar"
all=0
while [ $# -gt 0 ]; do
  case "$1" in
    --all) all=1 ;;
    --paths) paths="${2:?--paths needs a list such as avx2,scalar}"; shift ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
bash scripts/install_deps.sh
flags=" $(grep -m1 '^flags' /proc/cpuinfo | cut -d: -f2) "
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
IFS=, read -r -a wanted <<< "$paths"
for path in "${wanted[@]}"; do
  case "$path" in
    avx512) arch=x86-64-v4; needs="avx512f avx512dq avx512bw avx512vl" ;;
    avx2) arch=x86-64-v3; needs="avx2 fma bmi2" ;;
    scalar) arch=x86-64-v2; needs="sse4_2 popcnt" ;;
    *) echo "error: unknown path '$path' (avx512, avx2 or scalar)" >&2; exit 2 ;;
  esac
  missing=""
  for f in $needs; do [[ "$flags" == *" $f "* ]] || missing+=" $f"; done
  if [ -n "$missing" ]; then
    echo "test_simd_paths: skipping $path: this CPU lacks$missing" >&2
    continue
  fi
  dir="build-simd-$path"
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release -DSTREETLIGHT_ARCH="$arch" > "$dir.configure.log" 2>&1 \
    || { cat "$dir.configure.log" >&2; exit 1; }
  if [ "$all" -eq 1 ]; then
    cmake --build "$dir" -j"$(nproc)"
    exclude='^$'
  else
    cmake --build "$dir" -j"$(nproc)" --target util_tests autodiff_tests nn_tests render_tests
    exclude='_NOT_BUILT$|^PackageConsumer$|^python_tests$'  # the tests of what this build skipped
  fi
  echo "test_simd_paths: $path kernels (-march=$arch, STREETLIGHT_SIMD=$path)" >&2
  STREETLIGHT_SIMD="$path" ctest --test-dir "$dir" --output-on-failure -j"$(nproc)" --timeout 300 -E "$exclude"
done
