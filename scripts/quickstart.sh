#!/usr/bin/env bash
# The README's first command: installs what it needs, builds, then runs the main job on data the
# project makes itself: generate a small synthetic street dataset, train the three quickstart
# stages (sky autoencoder, lighting predictor, end to end with insertion), evaluate on the held-out
# split, and insert a held-out image's own object into it (beside its path-traced truth). Writes a Markdown report
# with the metrics table and PNGs under the output folder (default streetlight-out/).
# Usage: scripts/quickstart.sh [--out DIR] [--skip-install] [--build-dir DIR [--skip-build]]
# Works without ../shared (the sky stage then trains on sky-model skies only).
set -euo pipefail
cd "$(dirname "$0")/.."
out=streetlight-out; install=1; build_dir=build; build=1
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift ;;
    --skip-install) install=0 ;;
    --build-dir) build_dir="$2"; shift ;;
    --skip-build) build=0 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
[ "$install" = 1 ] && bash scripts/install_deps.sh
dir="$build_dir"
[ "$build" = 1 ] && dir=$(bash scripts/build.sh --dir "$build_dir" | tail -n 1)
bin="$dir/tools"
mkdir -p "$out"
out=$(cd "$out" && pwd)
runs="$out/runs"
mkdir -p "$runs"
start=$(date +%s)
step() { echo "quickstart: [$(( $(date +%s) - start )) s] $*" >&2; }

hdri=""
[ -d ../shared/data/hdri ] && hdri=$(cd ../shared/data/hdri && pwd)

step "1/5 generating the synthetic street dataset (configs/datagen_quickstart.json)"
"$bin/streetlight-datagen" --config configs/datagen_quickstart.json --out "$runs/street" \
  --contact-sheet "$out/dataset.png" > "$runs/datagen.json"

step "2/5 stage 1: sky autoencoder${hdri:+ (with the HDRIs in $hdri)}"
split=()  # with the real panoramas, stage 1 sees only the training skies of configs/hdri_split.json
[ -n "$hdri" ] && split=(--set data.hdri_split=configs/hdri_split.json)
"$bin/streetlight-train" --config configs/quickstart_sky.json --set "data.hdri_dir=$hdri" "${split[@]}" \
  --out "$runs/sky" > "$runs/sky.json"
step "3/5 stage 2: lighting predictor"
"$bin/streetlight-train" --config configs/quickstart_lighting.json --set "data.dataset=$runs/street" \
  --set "init.sky_checkpoint=$runs/sky/last.safetensors" --out "$runs/lighting" > "$runs/lighting.json"
step "3/5 stage 3: end to end through object insertion"
"$bin/streetlight-train" --config configs/quickstart_adversarial.json --set "data.dataset=$runs/street" \
  --set "init.checkpoint=$runs/lighting/last.safetensors" --out "$runs/adversarial" > "$runs/adversarial.json"

step "4/5 evaluating on the test split"
"$bin/streetlight-eval" --data "$runs/street" --split test --out "$out/eval" \
  --checkpoint "$runs/sky/last.safetensors" --name "stage 1 (sky)" \
  --checkpoint "$runs/lighting/last.safetensors" --name "stage 2 (lighting)" \
  --checkpoint "$runs/adversarial/last.safetensors" --name "stage 3 (adversarial)" > /dev/null

step "5/5 inserting a held-out generated image's own car into it"
sample=$(ls -d "$runs"/street/samples/* | tail -n 1)
for s in "$runs"/street/samples/*; do  # the first test-split sample
  id=$(basename "$s")
  if tr -d ' \n' < "$runs/street/index.json" | grep -q "\"test\":\[[^]]*\"$id\""; then sample="$s"; break; fi
done
"$bin/streetlight-insert" --sample "$sample" \
  --checkpoint "$runs/adversarial/last.safetensors" --out "$out/insertion"
cp "$sample/insert_with_object_ldr.png" "$out/insertion/path_traced_truth.png" 2>/dev/null || true
cp "$sample/view_0_ldr.png" "$out/insertion/input.png"

elapsed=$(( $(date +%s) - start ))
{
  echo "# Streetlight quickstart report"
  echo
  echo "Synthetic street dataset (\`configs/datagen_quickstart.json\`), the three quickstart stages"
  echo "(\`configs/quickstart_*.json\`), evaluated on the held-out test split. Wall time: ${elapsed} s"
  echo "(after the build). Sky stage HDRIs: ${hdri:-none (sky-model skies only)}."
  echo
  echo "## Metrics (streetlight-eval)"
  echo
  cat "$out/eval/results.md"
  echo
  echo "Sun errors in degrees; PSNR in dB on the LDR novel views (si-PSNR: least-squares scale);"
  echo "insertion PSNR over the object and its shadow against the path-traced ground truth."
  echo
  echo "## Insertion into a held-out image ($(basename "$sample"))"
  echo
  echo "| input | ours (composite) | path-traced ground truth |"
  echo "|---|---|---|"
  echo "| ![](insertion/input.png) | ![](insertion/composite.png) | ![](insertion/path_traced_truth.png) |"
  echo
  echo "Estimated sky: ![](insertion/sky.png)"
  echo
  echo "Error against run time: ![](eval/error_time.png)"
  echo
  echo "Dataset contact sheet: ![](dataset.png)"
} > "$out/REPORT.md"
echo "quickstart: finished in ${elapsed} s; report: $out/REPORT.md" >&2
