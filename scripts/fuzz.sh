#!/usr/bin/env bash
# Builds the libFuzzer harnesses of tests/fuzz (clang 14, ASan + UBSan, build-fuzz/) and runs
# them ONE AT A TIME under nice, then prints executions, time, exec/s, corpus (units/bytes) and crash
# files per target.
# Not part of CI: CI replays the committed corpora (fuzz_tests, tests/fuzz/corpus_replay_test.cpp).
#
#   scripts/fuzz.sh [TARGET ...] [--seconds N] [--runs N] [--markdown] [--build-only]
#
# --build-only builds every library, every tool and every harness with clang and stops (CI runs it,
# so that code clang refuses cannot land unnoticed).
# TARGET: safetensors gltf image kitti calibration_json dataset config rays batch_list sun_labels tflite (default:
# all). Each run stops after N seconds (default 60) or N executions, whichever comes first.
# --markdown prints the table as Markdown rows (tests/fuzz/README.md keeps the measured one). The
# working corpus grows in build-fuzz/fuzz-corpus/<target>/ (seeded from tests/fuzz/corpus/);
# crashing, leaking, timing-out and out-of-memory inputs land in build-fuzz/fuzz-crashes/<target>/
# — add each to tests/fuzz/corpus/<target>/ once fixed. Logs: build-fuzz/fuzz-logs/<target>.log.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${STREETLIGHT_FUZZ_BUILD:-$root/build-fuzz}"
all=(safetensors gltf image kitti calibration_json dataset config rays batch_list sun_labels tflite)
seconds=60
runs=-1
build_only=0
markdown=0
targets=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --seconds) seconds="$2"; shift 2 ;;
    --runs) runs="$2"; shift 2 ;;
    --build-only) build_only=1; shift ;;
    --markdown) markdown=1; shift ;;
    -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "error: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *)
      if [[ ! " ${all[*]} " == *" $1 "* ]]; then
        echo "error: unknown target '$1' (targets: ${all[*]})" >&2; exit 2
      fi
      targets+=("$1"); shift ;;
  esac
done
[[ ${#targets[@]} -eq 0 ]] && targets=("${all[@]}")
command -v clang++ >/dev/null || { echo "error: clang++ not found: bash scripts/install_deps.sh --clang" >&2; exit 2; }

CC=clang CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-O1 \
  -DSTREETLIGHT_FUZZ=ON -DSTREETLIGHT_TESTS=OFF -DSTREETLIGHT_NATIVE=OFF >/dev/null
if [[ $build_only -eq 1 ]]; then
  # Everything: the libraries, the tools and the harnesses (the suites are GCC's, STREETLIGHT_TESTS=OFF).
  log="$build/build-all.log"
  nice -n 5 cmake --build "$build" -j"$(nproc)" > "$log" 2>&1 || { grep -E 'error|Error' "$log" | head -40 >&2; exit 1; }
  echo "fuzz.sh: clang built the libraries, the tools and ${#all[@]} harnesses in $build" >&2
  exit 0
fi
nice -n 5 cmake --build "$build" -j2 --target "${targets[@]/#/fuzz_}" >/dev/null

if [[ $markdown -eq 1 ]]; then
  row() { printf '| %s | %s | %s | %s | %s | %s |\n' "$@"; }
  row target executions seconds exec/s corpus crashes
  echo '|---|---:|---:|---:|---:|---:|'
else
  row() { printf '%-17s %12s %9s %8s %8s %8s\n' "$@"; }
  row target executions seconds exec/s corpus crashes
fi
for t in "${targets[@]}"; do
  work="$build/fuzz-corpus/$t" crashes="$build/fuzz-crashes/$t" log="$build/fuzz-logs/$t.log"
  mkdir -p "$work" "$crashes" "$(dirname "$log")"
  start=$(date +%s)
  # One thread: OpenMP loops in the loaders would otherwise compete with other users' work.
  # -timeout is wall-clock: on a shared, loaded machine 10 s flagged ordinary inputs (a dataset
  # sample reads a dozen images), so only inputs stuck for a minute count as hangs.
  OMP_NUM_THREADS=1 nice -n 10 "$build/tests/fuzz/libfuzzer/fuzz_$t" "$work" "$root/tests/fuzz/corpus/$t" \
    -max_total_time="$seconds" -runs="$runs" -timeout=60 -rss_limit_mb=4096 -malloc_limit_mb=3072 \
    -artifact_prefix="$crashes/" -print_final_stats=1 >"$log" 2>&1 || true
  elapsed=$(( $(date +%s) - start ))
  # Final stats after a clean stop; after a crash, the last progress line ("#N ...").
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' ||
          grep -o '^#[0-9]*' "$log" | tail -1 | tr -d '#' || true)
  # libFuzzer's own corpus at the end ("corp: units/bytes"); the folder also keeps superseded units.
  corpus=$(grep -a -o 'corp: [0-9]*/[0-9]*[a-zA-Z]*' "$log" | tail -1 | cut -d' ' -f2 || true)
  row "$t" "${execs:-0}" "$elapsed" "$(( ${execs:-0} / (elapsed > 0 ? elapsed : 1) ))" "${corpus:-?}" \
    "$(ls "$crashes" | wc -l)"
done
