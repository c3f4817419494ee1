#!/usr/bin/env bash
# Side-by-side ray throughput: render/bvh (streetlight-bench trace) vs Embree 3 rtcIntersect1.
# Usage: scripts/compare_embree.sh [BUILD_DIR] [RAYS]    (defaults: build, 1000000)
# Needs streetlight-bench and streetlight-embree-trace (built when libembree-dev is installed),
# ../shared/data/models/CesiumMilkTruck.glb, and /usr/bin/python3 with numpy.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
count="${2:-1000000}"
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
printf '%-18s %-8s %9s %9s %7s %9s %9s %7s %8s %8s %7s\n' mesh rays ours_ch embree_ch ratio ours_any embree_any ratio build_us build_em agree
for mesh in "$truck" "$work/bumpy200k.glb"; do
  name="$(basename "$mesh" .glb)"
  for kind in primary random; do
    rays="$work/$name.$kind.rays"
    "$bench" gen-rays --mesh "$mesh" --kind "$kind" --count "$count" --seed 1 --out "$rays" 2>/dev/null
    ours="$("$bench" trace --mesh "$mesh" --rays "$rays" --hits-out "$work/ours.hits" --json)"
    theirs="$("$embree" --mesh "$mesh" --rays "$rays" --hits-out "$work/embree.hits" --json)"
    agree="$(/usr/bin/python3 "$root/scripts/compare_hits.py" "$work/ours.hits" "$work/embree.hits" --rel 1e-4)"
    oc="$(field closest_mrays_per_s <<<"$ours")"; ec="$(field closest_mrays_per_s <<<"$theirs")"
    oa="$(field any_mrays_per_s <<<"$ours")"; ea="$(field any_mrays_per_s <<<"$theirs")"
    ob="$(field build_ms <<<"$ours")"; eb="$(field build_ms <<<"$theirs")"
    /usr/bin/python3 - "$name" "$kind" "$oc" "$ec" "$oa" "$ea" "$ob" "$eb" "$agree" <<'PY'
import sys
n, k, oc, ec, oa, ea, ob, eb, ag = sys.argv[1:]
oc, ec, oa, ea, ob, eb = map(float, (oc, ec, oa, ea, ob, eb))
print(f"{n[:18]:<18} {k:<8} {oc:9.2f} {ec:9.2f} {oc/ec:7.2f} {oa:9.2f} {ea:9.2f} {oa/ea:7.2f} {ob:8.1f} {eb:8.1f} {float(ag):7.4f}")
PY
  done
done
echo "(Mrays/s, best of 5, OMP_NUM_THREADS=${OMP_NUM_THREADS:-all}; ratio = ours/Embree; build in ms; agree = share of rays with equal hit/miss and t within 1e-4 relative)"
