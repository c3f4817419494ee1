#!/usr/bin/env bash
# Side-by-side ray throughput on the BVH benchmark set: render/bvh (streetlight-bench trace) vs
# Embree 3 rtcIntersect1 / rtcOccluded1.
# Usage: [SETTLE_S=S] scripts/compare_embree.sh [BUILD_DIR] [RAYS] [ROUNDS] [MESH...]
#   defaults: build, 1000000, 3, every mesh of the set. MESH: a name from the set below. SETTLE_S:
#   seconds to wait after writing the meshes and rays, before the first measurement (default 30).
# Each mesh x {primary, random} rays runs both sides ROUNDS times, alternating, and prints the
# medians of the throughputs, the median of the per-round ratios ours/Embree and their range
# (min-max over the rounds), for closest hit and any hit: on a loaded machine one round's ratio
# can be far off.
#
# The benchmark set (issue 52; docs/benchmarks.md "BVH benchmark set"):
#   name       kind                         source
#   truck      vehicle                      ../shared/data/models/CesiumMilkTruck.glb (2.9k)
#   machine    CAD, many small parts        gen-mesh --kind machine --triangles 120000 --seed 1
#   facade     architecture, street blocks  gen-mesh --kind facade  --triangles 200000 --seed 1
#   blob       organic, scan-like           gen-mesh --kind blob    --triangles 300000 --seed 1
#   foliage    thin overlapping slivers     gen-mesh --kind foliage --triangles 200000 --seed 1
#   terrain    heightfield, over 1M         gen-mesh --kind terrain --triangles 1200000 --seed 1
# HELD OUT: machine and facade. They were chosen before any result on the set was seen and are
# never used to tune the BVH (build parameters, traversal); they are reported in their own section.
#
# Needs streetlight-bench and streetlight-embree-trace (built when libembree-dev is installed),
# ../shared/data/models/CesiumMilkTruck.glb, and /usr/bin/python3 with numpy.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
count="${2:-1000000}"
rounds="${3:-3}"
shift $(( $# < 3 ? $# : 3 ))
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "error: ROUNDS must be a positive integer, got '$rounds'" >&2; exit 2; }
bench="$build/tools/streetlight-bench"
embree="$build/tools/compare/streetlight-embree-trace"
for exe in "$bench" "$embree"; do
  [[ -x "$exe" ]] || { echo "error: $exe not built" >&2; exit 2; }
done
truck="$root/../shared/data/models/CesiumMilkTruck.glb"
[[ -f "$truck" ]] || { echo "error: $truck not found" >&2; exit 2; }

declare -A gen=(
  [machine]="--kind machine --triangles 120000 --seed 1"
  [facade]="--kind facade --triangles 200000 --seed 1"
  [blob]="--kind blob --triangles 300000 --seed 1"
  [foliage]="--kind foliage --triangles 200000 --seed 1"
  [terrain]="--kind terrain --triangles 1200000 --seed 1"
)
held_out=(machine facade)
all=(truck machine facade blob foliage terrain)
selected=("$@")
[[ ${#selected[@]} -gt 0 ]] || selected=("${all[@]}")
for name in "${selected[@]}"; do
  [[ " ${all[*]} " == *" $name "* ]] || { echo "error: unknown mesh '$name' (one of: ${all[*]})" >&2; exit 2; }
done

# In memory (/dev/shm) when there is one: no file of the run is written back to disk.
work="$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)"
trap 'rm -rf "$work"' EXIT
rows="$work/rows.txt"
: > "$rows"
field() { /usr/bin/python3 -c "import json,sys; print(json.loads(sys.stdin.read())['$1'])"; }
mesh_of() { [[ "$1" == truck ]] && echo "$truck" || echo "$work/$1.glb"; }
# Every mesh and ray file is written before the first measurement, then flushed, and the runs wait
# SETTLE_S seconds (default 30): on this project's 2-vCPU VMs, for a minute or so after the guest
# writes or deletes a few hundred MB, our traversal loses up to half its throughput and Embree a
# fifth (docs/benchmarks.md, "the slow state"), so files written between measurements biased the
# first ray kind measured after each mesh.
for name in "${selected[@]}"; do
  [[ "$name" == truck ]] || "$bench" gen-mesh ${gen[$name]} --out "$(mesh_of "$name")" 2>/dev/null
  for kind in primary random; do
    "$bench" gen-rays --mesh "$(mesh_of "$name")" --kind "$kind" --count "$count" --seed 1 \
      --out "$work/$name.$kind.rays" 2>/dev/null
  done
done
sync
sleep "${SETTLE_S:-30}"
for name in "${selected[@]}"; do
  mesh="$(mesh_of "$name")"
  group=tuning
  [[ " ${held_out[*]} " == *" $name "* ]] && group=held-out
  for kind in primary random; do
    rays="$work/$name.$kind.rays"
    results=()
    tris=0
    for ((round = 0; round < rounds; ++round)); do
      # The side that runs first alternates from round to round; the last round writes the hits.
      ours_out=() theirs_out=()
      (( round == rounds - 1 )) && ours_out=(--hits-out "$work/ours.hits") theirs_out=(--hits-out "$work/embree.hits")
      run_ours() { ours="$("$bench" trace --mesh "$mesh" --rays "$rays" "${ours_out[@]}" --json 2> >(grep -v " ran on: " >&2))"; }
      run_theirs() { theirs="$("$embree" --mesh "$mesh" --rays "$rays" "${theirs_out[@]}" --json)"; }
      if (( round % 2 == 0 )); then run_ours; run_theirs; else run_theirs; run_ours; fi
      tris="$(field triangles <<<"$ours")"
      for key in closest_mrays_per_s any_mrays_per_s build_ms; do
        results+=("$(field $key <<<"$ours")" "$(field $key <<<"$theirs")")
      done
    done
    agree="$(/usr/bin/python3 "$root/scripts/compare_hits.py" "$work/ours.hits" "$work/embree.hits" --rel 1e-4)"
    echo "$group $name $tris $kind $agree ${results[*]}" >> "$rows"
  done
done

/usr/bin/python3 - "$rows" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1]) if l.strip()]
head = (f"{'mesh':<9} {'tris':>8} {'rays':<8} {'ours_ch':>8} {'embr_ch':>8} {'ratio':>5} {'range':>9}  "
        f"{'ours_any':>8} {'embr_any':>8} {'ratio':>5} {'range':>9}  {'build_us':>8} {'build_em':>8} {'agree':>8}")
for group, title in (("tuning", "tuning set"), ("held-out", "HELD OUT (never used for tuning)")):
    sel = [r for r in rows if r[0] == group]
    if not sel:
        continue
    print(f"== {title}")
    print(head)
    ratios = []
    for g, name, tris, kind, agree, *vals in sel:
        v = list(map(float, vals))
        rounds = [v[i:i + 6] for i in range(0, len(v), 6)]
        med = lambda j: statistics.median(r[j] for r in rounds)
        rs = lambda j: [r[j] / r[j + 1] for r in rounds]
        cells = []
        for j in (0, 2):
            q = rs(j)
            ratios.append(statistics.median(q))
            cells.append(f"{med(j):8.2f} {med(j + 1):8.2f} {statistics.median(q):5.2f} {min(q):4.2f}-{max(q):4.2f}")
        print(f"{name:<9} {int(tris):>8} {kind:<8} {cells[0]}  {cells[1]}  {med(4):8.1f} {med(5):8.1f} {float(agree):8.6f}")
    geo = 1.0
    for r in ratios:
        geo *= r
    print(f"   {title}: min ratio {min(ratios):.2f}, geometric mean {geo ** (1 / len(ratios)):.2f} over {len(ratios)} rows")
PY
echo "(CPU: $(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), family $(grep -m1 '^cpu family' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'); $(date -u '+%Y-%m-%d %H:%M UTC'); load $(cut -d' ' -f1-3 /proc/loadavg); $count rays; Mrays/s, best of 5 passes, median of $rounds rounds, OMP_NUM_THREADS=${OMP_NUM_THREADS:-all}; ratio = median of the rounds' ours/Embree, range = min-max of them; ch = closest hit, any = any hit; build in ms; agree = share of rays with equal hit/miss and t within 1e-4 relative, last round)"
