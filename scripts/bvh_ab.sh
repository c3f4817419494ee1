#!/usr/bin/env bash
# In-process A/B of render/bvh, for a loaded machine: two versions of render/bvh*.{h,cpp} (or one
# and Embree 3) are linked into one program that traces the rays of compare_embree.sh's four rows
# with each, alternating pass by pass on one thread, and reports throughput from the least
# thread-CPU time. Each pair is run twice with the two versions in swapped link slots and the
# ratio is the geometric mean of both (code placement alone moved one slot by up to 2-8%).
# Usage: scripts/bvh_ab.sh [--build DIR] [--passes N] BASE NEW
#   BASE, NEW: a git revision (its render/bvh*), or "." for the working tree; NEW may be "embree"
#   (then "differ" counts every t not bit-equal, which is most hits).
# Needs the build's libstreetlight_render.a, libstreetlight_util.a and streetlight-bench.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build"; passes=6
while [[ $# -gt 2 ]]; do
  case "$1" in
    --build) build="$(cd "$2" && pwd)"; shift 2 ;;
    --passes) passes="$2"; shift 2 ;;
    *) break ;;
  esac
done
[[ $# -eq 2 ]] || { sed -n '2,10p' "$0" >&2; exit 2; }
base="$1"; new="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
here="$root/scripts/bvh_ab"
flags=(-O3 -DNDEBUG -march=native -fopenmp -std=c++20 -isystem /usr/include/eigen3 -w)

sources() {  # sources REV DIR: render/bvh*.{h,cpp} of REV ("." = working tree) into DIR/render
  mkdir -p "$2/render"
  for f in bvh.h bvh.cpp bvh_build.cpp; do
    if [[ "$1" == "." ]]; then cp "$root/render/$f" "$2/render/$f"; else git -C "$root" show "$1:render/$f" > "$2/render/$f"; fi
  done
}
objects() {  # objects DIR SLOT OUT: one variant's objects, its namespace renamed sl -> slSLOT
  local d="$1" v="$2" o="$3"
  c++ "${flags[@]}" -Dsl=sl$v -I"$d" -I"$root" -ffp-contract=off -c "$d/render/bvh.cpp" -o "$o/${v}bvh.o" &
  c++ "${flags[@]}" -Dsl=sl$v -I"$d" -I"$root" -c "$d/render/bvh_build.cpp" -o "$o/${v}build.o" &
  c++ "${flags[@]}" -Dsl=sl$v "-DPFX(n)=${v}_##n" -I"$d" -I"$root" -c "$here/variant.cpp" -o "$o/${v}variant.o" &
  wait
}
link() {  # link OBJDIR OUT [extra libs]
  local o="$1" out="$2"; shift 2
  c++ -fopenmp -o "$out" "$o"/*.o "$build/render/libstreetlight_render.a" "$build/util/libstreetlight_util.a" \
    -ltinygltf -lOpenImageIO -lOpenImageIO_Util "$@"
}

sources "$base" "$work/base"
mkdir -p "$work/o1" "$work/o2"
c++ "${flags[@]}" -I"$root" -c "$here/main.cpp" -o "$work/main.o"
cp "$work/main.o" "$work/o1/" && cp "$work/main.o" "$work/o2/"
if [[ "$new" == embree ]]; then
  objects "$work/base" A "$work/o1"
  c++ "${flags[@]}" -c "$here/embree.cpp" -o "$work/o1/Bembree.o"
  link "$work/o1" "$work/ab" -lembree3
else
  sources "$new" "$work/new"
  objects "$work/base" A "$work/o1" && objects "$work/new" B "$work/o1"
  objects "$work/new" A "$work/o2" && objects "$work/base" B "$work/o2"
  link "$work/o1" "$work/ab" && link "$work/o2" "$work/ba"
fi

bench="$build/tools/streetlight-bench"
"$bench" gen-mesh --triangles 200000 --out "$work/bumpy200k.glb" 2>/dev/null
echo "load $(cut -d' ' -f1-3 /proc/loadavg), $passes passes, 1 thread; ratio = $new / $base (throughput), hits differing"
for mesh in "$root/../shared/data/models/CesiumMilkTruck.glb" "$work/bumpy200k.glb"; do
  for kind in primary random; do
    rays="$work/rays.bin"
    "$bench" gen-rays --mesh "$mesh" --kind "$kind" --count 1000000 --seed 1 --out "$rays" 2>/dev/null
    one="$(OMP_NUM_THREADS=1 "$work/ab" "$mesh" "$rays" "$passes")"
    two=""
    [[ -x "$work/ba" ]] && two="$(OMP_NUM_THREADS=1 "$work/ba" "$mesh" "$rays" "$passes")"
    /usr/bin/python3 - "$(basename "$mesh" .glb)" "$kind" "$one" "$two" <<'PY'
import math, sys
name, kind, one, two = sys.argv[1:5]
rows = lambda s: {l.split()[0]: l.split()[1:] for l in s.splitlines()}
a, b = rows(one), rows(two) if two else None
for q in ("closest", "any"):
    ta, tb, med, diff = a[q]
    r = float(med)  # median per-pass throughput B/A (time A / time B) = NEW/BASE
    if b:  # swapped slots: there B is BASE
        r = math.sqrt(r / float(b[q][2]))
    print(f"{name[:18]:<18} {kind:<8} {q:<8} base {float(ta):7.2f}  new {float(tb):7.2f} Mrays/s  ratio {r:.3f}  differ {diff}")
PY
  done
done
echo "load $(cut -d' ' -f1-3 /proc/loadavg)"
