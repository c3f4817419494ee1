#!/usr/bin/env bash
# Trains the released model (0.7.4: models/streetlight.safetensors and models/sun_glare.safetensors)
# from nothing. Steps, each resumable (a killed run continues where it stopped, bit-identically for
# the training stages):
#   The base model (release 0.6.0, 2026-11-27):
#   1. the synthetic streets (configs/release_datagen.json), a third of them lit by the training
#      panoramas of configs/hdri_split.json, rendered by two processes; then 320 held-out test
#      streets (configs/release_datagen_test.json: another seed, all in the test split) for a
#      synthetic sun error whose interval is narrow enough to read (the run's own test split
#      holds only a tenth of its streets);
#   2. stage 1, the sky autoencoder (configs/release_sky.json) on the split's training panoramas
#      and sky-model skies;
#   3. stage 2, the lighting predictor (configs/release_lighting.json) on the streets mixed with
#      perspective crops of the training HDR panoramas and of the labelled LDR street panoramas
#      (../shared/data/pano_ldr, configs/pano_ldr_split.json);
#   4. the sun's energy (configs/release_sun.json): stage 2 continued for 400 steps with the sun
#      lobe's energy supervised by the true sun's (loss.sun_energy) in place of the stage-1
#      encoder's intensity pseudo-label, which sees a clipped sun (docs/RESULTS.md);
#   5. the energy bounded on LDR crops (configs/release_sun_ldr.json): 1500 more steps at 80% streets
#      with loss.ldr_sun_energy, which keeps the sun of unlabelled camera photos in the energy span
#      of the labelled ones;
#   6. the streets (configs/release_streets.json): 1000 steps on the generated streets alone at a
#      lower rate; its checkpoint with the lowest validation error on the streets is the base model;
#   7. the base model's evaluation on the test splits (DIR/eval) and its card (DIR/base_model_card.md,
#      scripts/write_model_card.sh);
#   The release (0.7.4):
#   8. the sun head (release 0.7.2): scripts/train_sun_grid.sh --previous DIR/streets/best.safetensors
#      into DIR/sun_grid: a probability over sun directions trained on 480 streets and the enlarged
#      real data, then the backbone widened to 64 channels for 20000 steps; the 480 streets are the
#      first 480 of step 1's, hard-linked rather than rendered again (--streets-from); each of its
#      four parts validates once, at its end (--validate-at-end: its last checkpoint, which the next
#      part and the release take, is the same bits as with validation every 500 or 1000 steps);
#   9. the sun-glare detector and its azimuth head: scripts/train_sun_glare.sh into DIR/glare;
#  10. the release's evaluation on the test splits (DIR/release_eval: the sun head with the detector);
#  11. the release: step 8's last.safetensors exported (F16) to models/streetlight.safetensors and
#      step 9's detector copied to models/sun_glare.safetensors. The model card (models/README.md) is
#      written by hand from DIR/release_eval/results.md: it also describes the pictures. Stage 3
#      (configs/release_adversarial.json) is not part of the recipe: validation chose the stage
#      before it (models/README.md).
# Wall time on an AMD EPYC with 2 vCPUs: about 9 h (about 3 h 20 min to step 7, 4 h 40 min for step 8,
# 1 h 15 min for step 9), measured part by part and partly under load (models/README.md); step 8's
# figure includes 1932 s of rendering its 480 streets, which it now links from step 1 in under a
# second (0.015 s for 40 on an AMD EPYC; the same files), and 38 validations, of which it now runs 4
# (one at width 64 takes 29 s on an AMD EPYC: 19 fewer save about 550 s in part 4; parts 1-3, at
# width 32, not measured). Re-estimated idle on an AMD EPYC at 66983e1 from 100-step timings of each
# config: about 21 300 s (5.9 h) in all (docs/RESULTS.md, 2026-12-03).
# Usage: scripts/train_release.sh [--runs DIR] [--build-dir DIR] [--skip-build] [--no-publish]
#                                  [--stop-after STEP]
#   --runs DIR     run folder (default ../streetlight-runs/release, outside the repository)
#   --no-publish   train and evaluate only; leave models/ untouched
#   --stop-after STEP  stop once STEP is done (datagen, test_streets, sky, lighting, sun, sun_ldr,
#                      streets, eval, sun_grid, glare, release_eval)
# Needs ../shared/data/hdri (the real panoramas). Logs go to DIR/*.log; progress to stderr.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=../streetlight-runs/release; build_dir=build; build=1; publish=1; stop_after=
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift ;;
    --build-dir) build_dir="$2"; shift ;;
    --skip-build) build=0 ;;
    --no-publish) publish=0 ;;
    --stop-after) stop_after="$2"; shift
      case "$stop_after" in datagen|test_streets|sky|lighting|sun|sun_ldr|streets|eval|sun_grid|glare|release_eval) ;;
        *) echo "error: --stop-after '$stop_after': expected datagen, test_streets, sky, lighting, sun, sun_ldr, streets, eval, sun_grid, glare or release_eval" >&2; exit 2 ;;
      esac ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    *) echo "error: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
  shift
done
hdri=../shared/data/hdri; ldr=../shared/data/pano_ldr
[ -d "$hdri" ] || { echo "error: $hdri is missing: the release trains on the real panoramas there" >&2; exit 2; }
[ -f "$ldr/sun_labels.csv" ] || { echo "error: $ldr/sun_labels.csv is missing: the release trains on the labelled LDR panoramas there" >&2; exit 2; }
if [ "$build" = 1 ]; then bash scripts/install_deps.sh; build_dir=$(bash scripts/build.sh --dir "$build_dir" | tail -n 1); fi
bin="$build_dir/tools"
mkdir -p "$runs"
runs=$(cd "$runs" && pwd)
hdri=$(cd "$hdri" && pwd); ldr=$(cd "$ldr" && pwd)
start=$(date +%s)
say() { echo "train_release: [$(( $(date +%s) - start )) s] $*" >&2; }
timed() {  # timed NAME CMD...: runs CMD unless NAME is done; records its wall time
  local name=$1; shift
  if [ -f "$runs/$name.done" ]; then say "$name: done before ($(cat "$runs/$name.done") s)"
  else
    local t0; t0=$(date +%s)
    "$@"
    echo $(( $(date +%s) - t0 )) > "$runs/$name.done"
  fi
  if [ "$name" = "$stop_after" ]; then say "stopping after $name (--stop-after)"; exit 0; fi
}
# Resumes a stage from its last checkpoint when one exists.
train_stage() {  # train_stage NAME CONFIG [--set ...]
  local name=$1 config=$2; shift 2
  local resume=()
  [ -f "$runs/$name/last.safetensors" ] && resume=(--resume "$runs/$name/last.safetensors")
  say "stage $name ($config)${resume:+, resuming}"
  "$bin/streetlight-train" --config "$config" "$@" "${resume[@]}" --out "$runs/$name" --json \
    > "$runs/$name.json" 2> >(tee -a "$runs/$name.log" >&2)
  # SIGINT/SIGTERM make streetlight-train save and exit 0 with "interrupted": a stage cut short must
  # not be recorded as done, or the next run would go on from its partial weights.
  if grep -q '"interrupted":true' "$runs/$name.json"; then
    echo "train_release: $name was interrupted (last.safetensors saved); run the same command again to resume it" >&2
    exit 130
  fi
}

datagen() {  # datagen CONFIG OUT_NAME: two processes, one shard each
  local pids=()
  for k in 0 1; do
    OMP_NUM_THREADS=1 "$bin/streetlight-datagen" --config "$1" \
      --set "sky.hdri_folder=$hdri" --set sky.hdri_split=configs/hdri_split.json \
      --out "$runs/$2" --shard "$k/2" --skip-existing --json > "$runs/${2}_datagen_$k.json" 2> "$runs/${2}_datagen_$k.log" &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || { echo "error: streetlight-datagen failed, see $runs/${2}_datagen_*.log" >&2; exit 1; }; done
}
say "1/11 synthetic streets (configs/release_datagen.json, configs/release_datagen_test.json), 2 processes"
timed datagen datagen configs/release_datagen.json street
timed test_streets datagen configs/release_datagen_test.json test_street
timed sky train_stage sky configs/release_sky.json --set "data.hdri_dir=$hdri"
timed lighting train_stage lighting configs/release_lighting.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.sky_checkpoint=$runs/sky/best.safetensors"
timed sun train_stage sun configs/release_sun.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.sky_checkpoint=$runs/sky/best.safetensors" \
  --set "init.checkpoint=$runs/lighting/best.safetensors"
timed sun_ldr train_stage sun_ldr configs/release_sun_ldr.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.sky_checkpoint=$runs/sky/best.safetensors" \
  --set "init.checkpoint=$runs/sun/best.safetensors"
timed streets train_stage streets configs/release_streets.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.sky_checkpoint=$runs/sky/best.safetensors" \
  --set "init.checkpoint=$runs/sun_ldr/best.safetensors"

say "7/11 evaluating the base model's candidates, steps 5 and 6 (real HDR and LDR test splits, 8 crops per panorama; the held-out test streets)"
evaluate() {
  "$bin/streetlight-eval" --data "$hdri" --hdri-split configs/hdri_split.json --split test --crops 8 \
    --data "$ldr" --ldr-split configs/pano_ldr_split.json \
    --data "$runs/test_street" --baseline-data "$runs/street" --no-budgets --out "$runs/eval" \
    --checkpoint "$runs/sun_ldr/best.safetensors" --name "LDR energy span (sun_ldr)" \
    --checkpoint "$runs/streets/best.safetensors" --name "streets (the base model)" > /dev/null
  echo streets > "$runs/chosen"
  bash scripts/write_model_card.sh "$runs" > "$runs/base_model_card.md"
}
timed eval evaluate

say "8/11 the sun head (scripts/train_sun_grid.sh from the base model; logs in $runs/sun_grid/)"
timed sun_grid bash scripts/train_sun_grid.sh --runs "$runs/sun_grid" --build-dir "$build_dir" --no-publish \
  --previous "$runs/streets/best.safetensors" --streets-from "$runs/street" --validate-at-end --stop-after wide
say "9/11 the sun-glare detector (scripts/train_sun_glare.sh)"
timed glare bash scripts/train_sun_glare.sh --runs "$runs/glare" --build-dir "$build_dir" --no-publish

say "10/11 evaluating the release (the sun head with the detector) on the test splits"
release_evaluate() {
  "$bin/streetlight-eval" --data "$hdri" --hdri-split configs/hdri_split.json --split test --crops 8 \
    --data "$ldr" --ldr-split configs/pano_ldr_split.json --data "$runs/test_street" --baseline-data "$runs/street" \
    --no-budgets --out "$runs/release_eval" --sun-glare "$runs/glare/sun_glare.safetensors" \
    --checkpoint "$runs/sun_grid/wide_long/last.safetensors" --name "the release" > /dev/null
}
timed release_eval release_evaluate

if [ "$publish" = 1 ]; then
  commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
  "$bin/streetlight-export" --checkpoint "$runs/sun_grid/wide_long/last.safetensors" --out models/streetlight.safetensors \
    --meta "commit=$commit" --meta "script=scripts/train_release.sh" --meta "version=0.7.4" \
    --meta "license=see models/README.md"
  cp "$runs/glare/sun_glare.safetensors" models/sun_glare.safetensors
  say "11/11 published models/streetlight.safetensors and models/sun_glare.safetensors; write their card in models/README.md from $runs/release_eval/results.md"
fi
say "done in $(( $(date +%s) - start )) s (this invocation); per-step wall times in $runs/*.done"
