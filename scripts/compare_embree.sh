#!/usr/bin/env bash
# Side-by-side ray throughput: render/bvh (streetlight-bench trace) vs Embree 3 rtcIntersect1.
# Usage: scripts/compare_embree.sh [BUILD_DIR] [RAYS] [ROUNDS]    (defaults: build, 1000000, 3)
# Each row runs both sides ROUNDS times, alternating, and prints the medians of the throughputs
# and of the per-round ratios: on a loaded machine one round's ratio can be far off.
# Needs streetlight-bench and streetlight-embree-trace (built when libembree-dev is installed),
# ../shared/data/models/CesiumMilkTruck.glb, and /usr/bin/python3 with numpy.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
count="${2:-1000000}"
rounds="${3:-3}"
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "error: ROUNDS must be a positive integer, got '$rounds'" >&2; exit 2; }
bench="$build/tools/streetlight-bench"
embree="$build/tools/compare/streetlight-embree-trace"
for exe in "$bench" "$embree"; do
  [[ -x "$exe" ]] || { echo "error: $exe not built" >&2; exit 2; }
done
truck="$root/../shared/data/models/CesiumMilkTruck.glb"
[[ -f "$truck" ]] || { echo "error: $truck not found" >&2; exit 2; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$bench" gen-mesh --triangles 200000 --out "$work/bumpy200k.glb" 2>/dev/null

field() { /usr/bin/python3 -c "import json,sys; print(json.loads(sys.stdin.read())['$1'])"; }
printf '%-18s %-8s %9s %9s %7s %9s %9s %7s %8s %8s %9s\n' mesh rays ours_ch embree_ch ratio ours_any embree_any ratio build_us build_em agree
for mesh in "$truck" "$work/bumpy200k.glb"; do
  name="$(basename "$mesh" .glb)"
  for kind in primary random; do
    rays="$work/$name.$kind.rays"
    "$bench" gen-rays --mesh "$mesh" --kind "$kind" --count "$count" --seed 1 --out "$rays" 2>/dev/null
    results=()
    for ((round = 0; round < rounds; ++round)); do
      ours="$("$bench" trace --mesh "$mesh" --rays "$rays" --hits-out "$work/ours.hits" --json 2> >(grep -v " ran on: " >&2))"
      theirs="$("$embree" --mesh "$mesh" --rays "$rays" --hits-out "$work/embree.hits" --json)"
      for key in closest_mrays_per_s any_mrays_per_s build_ms; do
        results+=("$(field $key <<<"$ours")" "$(field $key <<<"$theirs")")
      done
    done
    agree="$(/usr/bin/python3 "$root/scripts/compare_hits.py" "$work/ours.hits" "$work/embree.hits" --rel 1e-4)"
    /usr/bin/python3 - "$name" "$kind" "$agree" "${results[@]}" <<'PY'
import statistics, sys
n, k, ag = sys.argv[1:4]
rounds = [list(map(float, sys.argv[i:i + 6])) for i in range(4, len(sys.argv), 6)]
med = lambda j: statistics.median(r[j] for r in rounds)
ratio = lambda j: statistics.median(r[j] / r[j + 1] for r in rounds)
print(f"{n[:18]:<18} {k:<8} {med(0):9.2f} {med(1):9.2f} {ratio(0):7.2f} {med(2):9.2f} {med(3):9.2f} {ratio(2):7.2f} {med(4):8.1f} {med(5):8.1f} {float(ag):9.6f}")
PY
  done
done
echo "(CPU: $(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'); Mrays/s, best of 5 passes, median of $rounds rounds, OMP_NUM_THREADS=${OMP_NUM_THREADS:-all}; ratio = median of the rounds' ours/Embree; build in ms; agree = share of rays with equal hit/miss and t within 1e-4 relative)"
