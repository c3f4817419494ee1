#!/usr/bin/env bash
# Pixel noise at equal samples per pixel: streetlight-render (stratified, and the old independent
# estimator) against Blender Cycles, CesiumMilkTruck on a ground plane, 160x90, under a hard-sun
# and a soft-sky HDRI. Optional; never used by the library or CI.
# Usage: scripts/compare_cycles.sh [BUILD_DIR] [SPP] [OUT_DIR] [SKIES]
#   (defaults: build, 256, a temp dir, "chinese_garden kloppenheim_05 potsdamer_platz dresden_square")
# Needs Debian's blender (3.4) and ../shared/data. Noise = sqrt(mean((seed1 - seed2)^2) / 2)
# over all pixels and channels (scripts/compare_cycles.py stats); ratios are to Cycles.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
spp="${2:-256}"
render="$build/tools/streetlight-render"
[[ -x "$render" ]] || { echo "error: $render not built" >&2; exit 2; }
command -v blender >/dev/null || { echo "error: blender not installed (apt-get install blender)" >&2; exit 2; }
data="$root/../shared/data"
truck="$data/models/CesiumMilkTruck.glb"
[[ -f "$truck" ]] || { echo "error: $truck not found" >&2; exit 2; }
if [[ -n "${3:-}" ]]; then work="$3"; mkdir -p "$work"; else work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT; fi
# The bench's three-quarter view of the truck (tools/bench/bench_render.cpp), written out.
view=(--cam 5.56,4.07,6.80 --look 0,1.29,0 --fov 50 --width 160 --height 90 --ground 0.3 --max-depth 8)
py() { blender -b --factory-startup -P "$root/scripts/compare_cycles.py" -- "$@" 2>/dev/null | grep '^{' || true; }
for sky in ${4:-chinese_garden kloppenheim_05 potsdamer_platz dresden_square}; do
  hdri="$data/hdri/${sky}_1k.hdr"
  [[ -f "$hdri" ]] || continue
  for est in stratified independent; do
    for seed in 1 2; do
      /usr/bin/time -f "{\"ours\":\"$sky/$est/$seed\",\"seconds\":%e}" "$render" --scene "$truck" --hdri "$hdri" \
        "${view[@]}" --spp "$spp" --seed "$seed" --estimator "$est" --out "$work/${sky}_${est}_$seed.exr" 2>&1 >/dev/null |
        grep '^{'
    done
  done
  mkdir -p "$work/$sky"
  # Cycles images already in OUT_DIR (same SPP) are reused: they take minutes on 2 cores.
  [[ -f "$work/$sky/cycles_seed2.exr" ]] ||
    py render --glb "$truck" --hdri "$hdri" "${view[@]}" --spp "$spp" --seeds 1,2 --out "$work/$sky"
  py stats "cycles/$sky" "$work/$sky/cycles_seed1.exr" "$work/$sky/cycles_seed2.exr" \
    "stratified/$sky" "$work/${sky}_stratified_1.exr" "$work/${sky}_stratified_2.exr" \
    "independent/$sky" "$work/${sky}_independent_1.exr" "$work/${sky}_independent_2.exr"
done
