#!/usr/bin/env bash
# Trains the released lighting model from nothing and publishes it as models/streetlight.safetensors
# with its model card (models/README.md). Steps, each resumable (a killed run continues where it
# stopped, bit-identically for the training stages):
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
#   5. stage 3, end to end through object insertion (configs/release_adversarial.json), from step 4;
#   6. evaluation of stages 2, 2b (sun) and 3 on the real HDR and LDR test splits and the
#      synthetic test split;
#   7. the release: of steps 4 and 5 (the two that learned the sun's energy), the checkpoint with
#      the lower VALIDATION sun error (never a test figure) is exported (F16) with a model card that
#      lists data, configs, steps, wall times, commit and the test metrics beside the constant
#      baseline.
# Usage: scripts/train_release.sh [--runs DIR] [--build-dir DIR] [--skip-build] [--no-publish]
#                                  [--stop-after STEP]
#   --runs DIR     run folder (default ../streetlight-runs/release, outside the repository)
#   --no-publish   train and evaluate only; leave models/ untouched
#   --stop-after STEP  stop once STEP is done (datagen, test_streets, sky, lighting, sun, adversarial,
#                      eval)
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
      case "$stop_after" in datagen|test_streets|sky|lighting|sun|adversarial|eval) ;;
        *) echo "error: --stop-after '$stop_after': expected datagen, test_streets, sky, lighting, sun, adversarial or eval" >&2; exit 2 ;;
      esac ;;
    -h|--help) sed -n '2,31p' "$0"; exit 0 ;;
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
say "1/7 synthetic streets (configs/release_datagen.json, configs/release_datagen_test.json), 2 processes"
timed datagen datagen configs/release_datagen.json street
timed test_streets datagen configs/release_datagen_test.json test_street
timed sky train_stage sky configs/release_sky.json --set "data.hdri_dir=$hdri"
timed lighting train_stage lighting configs/release_lighting.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.sky_checkpoint=$runs/sky/best.safetensors"
timed sun train_stage sun configs/release_sun.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.sky_checkpoint=$runs/sky/best.safetensors" \
  --set "init.checkpoint=$runs/lighting/best.safetensors"
timed adversarial train_stage adversarial configs/release_adversarial.json --set "data.hdri_dir=$hdri" --set "data.ldr_dir=$ldr" \
  --set "data.dataset=$runs/street" --set "init.checkpoint=$runs/sun/best.safetensors"

say "6/7 evaluating stages 2, 2b and 3 (real HDR and LDR test splits, 8 crops per panorama; the held-out test streets)"
evaluate() {
  "$bin/streetlight-eval" --data "$hdri" --hdri-split configs/hdri_split.json --split test --crops 8 \
    --data "$ldr" --ldr-split configs/pano_ldr_split.json \
    --data "$runs/test_street" --baseline-data "$runs/street" --no-budgets --out "$runs/eval" \
    --checkpoint "$runs/lighting/best.safetensors" --name "stage 2 (lighting)" \
    --checkpoint "$runs/sun/best.safetensors" --name "stage 2b (sun energy)" \
    --checkpoint "$runs/adversarial/best.safetensors" --name "stage 3 (adversarial)" > /dev/null
}
timed eval evaluate

# The release is chosen on validation: the best_metric each stage stored with its best checkpoint.
best_of() {  # the best_metric value a stage stored with its best checkpoint
  "$bin/streetlight-export" --checkpoint "$1" --info | sed -n 's/.*"best_metric":"\([^"]*\)".*/\1/p'
}
# The sun stage's best_metric is its val_loss (it selects on the energy too), so its sun error is
# read from its metrics at the stored step.
val_sun_at_best() {  # val_sun_at_best STAGE: val_sun_error_median_deg at the step of STAGE's best checkpoint
  local step
  step=$("$bin/streetlight-export" --checkpoint "$runs/$1/best.safetensors" --info | sed -n 's/.*"step":"\{0,1\}\([0-9]*\).*/\1/p')
  python3 -c "import json,sys
for l in open(sys.argv[1]):
  d=json.loads(l)
  if d.get('split')=='val' and d['step']==int(sys.argv[2]): print(d['val_sun_error_median_deg'])" "$runs/$1/metrics.jsonl" "$step" | tail -n 1
}
v2=$(val_sun_at_best sun); v3=$(best_of "$runs/adversarial/best.safetensors")
chosen=sun
awk -v a="$v3" -v b="$v2" 'BEGIN { exit !(a + 0 < b + 0) }' && chosen=adversarial
say "7/7 validation sun error: stage 2b $v2, stage 3 $v3 -> releasing stage $chosen"
echo "$chosen" > "$runs/chosen"
if [ "$publish" = 1 ]; then
  commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
  "$bin/streetlight-export" --checkpoint "$runs/$chosen/best.safetensors" --out models/streetlight.safetensors \
    --meta "commit=$commit" --meta "script=scripts/train_release.sh" --meta "license=see models/README.md"
  bash scripts/write_model_card.sh "$runs" > models/README.md.tmp && mv models/README.md.tmp models/README.md
  say "published models/streetlight.safetensors and models/README.md"
fi
say "done in $(( $(date +%s) - start )) s (this invocation); per-step wall times in $runs/*.done"
