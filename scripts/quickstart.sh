#!/usr/bin/env bash
# The README's first command: installs what it needs, builds, and runs the main job on data the
# project makes itself, writing its results under an output folder (default: streetlight-out/).
# Today the main job is the autodiff + nn demo: an MLP fitted to a 2-D function it samples
# itself. Later stages (data generation, training, evaluation, insertion) join as they land.
# Usage: scripts/quickstart.sh [--out DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=streetlight-out
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift ;;
    -h|--help) sed -n '2,6p' "$0"; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
bash scripts/install_deps.sh
dir=$(bash scripts/build.sh | tail -n 1)
mkdir -p "$out"
start=$(date +%s)
"$dir/tools/streetlight-fit-demo" --json > "$out/fit_demo.json"
echo "quickstart: finished in $(( $(date +%s) - start )) s; results in $out/fit_demo.json" >&2
cat "$out/fit_demo.json"
