#!/usr/bin/env bash
# Trains the learned sun-glare detector of release 0.7.3 (train/sun_glare.h, issue 53) and publishes
# it as models/sun_glare.safetensors.
# `streetlight-bench sun-glare` draws the crops of the TRAIN splits (per labelled LDR panorama with a
# visible sun: 16 crops aimed at it, 4 just beside it, 8 at random; 8 random crops of every other
# panorama; 64 of the benchmark's crops of each training HDR sky), trains 16000 steps of batch 32 (Adam,
# lr 2e-3 cosine to 0, width 32), and then scores the detector beside the disk test on the VALIDATION
# split. The threshold (train/sun_glare.h, kGlareThreshold = 0.95) was chosen on that score.
# Usage: scripts/train_sun_glare.sh [--runs DIR] [--build-dir DIR] [--no-publish]
#   --runs DIR   run folder (default ../streetlight-runs/glare, outside the repository)
# Wall time here (AMD EPYC, 2 vCPUs, 2 threads, nearly idle): 117 s of crops and 1902 s of training
# (8.4 steps/s).
set -euo pipefail
cd "$(dirname "$0")/.."
runs=../streetlight-runs/glare; build_dir=build; publish=1
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="${2:?--runs needs a folder}"; shift ;;
    --build-dir) build_dir="${2:?--build-dir needs a folder}"; shift ;;
    --no-publish) publish=0 ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
data=../shared/data
bench="$build_dir/tools/streetlight-bench"
for f in "$data/pano_ldr/sun_labels.csv" "$data/hdri" "$bench"; do
  [ -e "$f" ] || { echo "error: $f not found (the shared data beside the repository, and a build)" >&2; exit 2; }
done
mkdir -p "$runs"
"$bench" sun-glare --data "$data/pano_ldr" --split-file configs/pano_ldr_split.json \
  --hdr-data "$data/hdri" --hdr-split-file configs/hdri_split.json \
  --steps 16000 --width 32 --aimed 16 --near 4 --random 8 --hdr-crops 64 \
  --out "$runs/sun_glare.safetensors" | tee "$runs/validation.txt"
if [ "$publish" = 1 ]; then
  cp "$runs/sun_glare.safetensors" models/sun_glare.safetensors
  echo "published models/sun_glare.safetensors"
fi
