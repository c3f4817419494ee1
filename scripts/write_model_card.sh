#!/usr/bin/env bash
# Writes the model card of the released weights (models/README.md) to stdout from a finished
# scripts/train_release.sh run folder: data and licences, configs, steps, wall times, commit, the
# test metrics beside the constant baseline (copied from the run's streetlight-eval results.md)
# and the known limits. Usage: scripts/write_model_card.sh RUN_DIR
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:?usage: scripts/write_model_card.sh RUN_DIR}
[ -f "$runs/eval/results.md" ] || { echo "error: $runs/eval/results.md is missing: run scripts/train_release.sh first" >&2; exit 2; }
chosen=$(cat "$runs/chosen")
secs() { cat "$runs/$1.done" 2>/dev/null || echo "?"; }
total=0
for s in datagen test_streets sky lighting sun sun_ldr streets eval; do v=$(secs $s); [ "$v" != "?" ] && total=$(( total + v )); done
steps() { sed -n 's/.*"steps": *\([0-9]*\).*/\1/p' "configs/release_$1.json" | head -n 1; }
samples() { sed -n 's/.*"samples": *\([0-9]*\).*/\1/p' "configs/release_$1.json" | head -n 1; }
fraction() { sed -n "s/.*\"$2\": *\\([0-9.]*\\).*/\\1/p" "configs/release_$1.json" | head -n 1; }
real_fraction=$(fraction lighting real_fraction)
ldr_fraction=$(fraction lighting ldr_fraction)
# Whether stages 2-3 saw real crops decides the card's mixing sentence and its depth limit.
if awk -v f="${real_fraction:-0}" 'BEGIN { exit !(f + 0 > 0) }'; then
  mixing="- Mixed in stage 2 at \`data.real_fraction = $real_fraction\` (crops of the real HDR panoramas) and
  \`data.ldr_fraction = ${ldr_fraction:-0}\` (crops of the real LDR street panoramas): random azimuth rotation, flips,
  white balance and exposure jitter; the rest are synthetic streets (configs/README.md, \"Mixing\")."
  depth_limit="- The real crops have no depth, so the volume branch learns geometry only from the synthetic streets."
else
  mixing="- Stages 2-3 train on the synthetic streets alone (\`data.real_fraction = 0\`). The mechanism that
  mixes in crops of real panoramas (random azimuth rotation, flips, white balance and exposure
  jitter) is in the recipe's configs and off."
  depth_limit="- Stages 2-3 never see a real photograph: real panoramas reach them only as the light of a third
  of the synthetic streets, so real photos are outside the training distribution."
fi
# The HDRI split's sizes, read from the file the release configs name.
split_count() { python3 -c "import json,sys; print(len(json.load(open(sys.argv[2]))[sys.argv[1]]))" "$1" "${2:-configs/hdri_split.json}"; }
n_train=$(split_count train) n_val=$(split_count val) n_test=$(split_count test)
l_train=$(split_count train configs/pano_ldr_split.json) l_val=$(split_count val configs/pano_ldr_split.json)
l_test=$(split_count test configs/pano_ldr_split.json)
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
size=$(du -h models/streetlight.safetensors 2>/dev/null | cut -f1)
cat <<EOF
# Model card: \`streetlight.safetensors\`

The lighting predictor of Streetlight (Wang et al., ECCV 2022, Sec 3.2: ResNet-18 backbone, sky head
with the frozen sky decoder, volume branch with its 3D UNet), trained by \`scripts/train_release.sh\`
on this repository's 2-core CPU machine. It is what \`streetlight-insert\` and \`streetlight-eval\` use
when \`--checkpoint\` is omitted. Released stage: **$chosen**, the last of the recipe: stage 2, then the
sun's energy (2b), the energy bounded on LDR crops, and 1000 steps on the generated streets alone (below).
Stored as F16 ($size); it loads into the float32 model. Made at commit \`$commit\`.

## Data
- **Real panoramas**: the $n_train training panoramas of \`configs/hdri_split.json\` (\`../shared/data/hdri\`,
  Poly Haven, CC0). $n_val are validation, $n_test test; the split is scene-disjoint and no validation or test
  sky is ever trained on (stage 1, stage-2/3 crops, or the light of generated streets).
- **Real LDR street panoramas**: the $l_train training panoramas of \`configs/pano_ldr_split.json\`
  (\`../shared/data/pano_ldr\`, MANIFEST.md there gives each file's source and licence), with the sun
  hand-labelled in \`sun_labels.csv\` (visible, occluded with the place its shadows give, or none). $l_val
  are validation, $l_test test, split by place. Stages 2-3 only (the stage-1 sky autoencoder needs HDR).
- **Synthetic streets**: \`configs/release_datagen.json\`, rendered by \`streetlight-datagen\` (path
  traced, 16 spp); a third of them lit by the training panoramas, the rest by the Preetham sky model.
  Objects inserted by the generator are procedural cars.
$mixing
- The sun's energy (stage 2b onwards, \`loss.sun_energy\`): the analytic sun lobe's energy is supervised by
  the true sun's Σ L·Ω within 5° wherever the sky is HDR and the sun known (generated streets, hard-sun
  HDR crops), in place of the stage-1 encoder's intensity pseudo-label (\`loss.sky_intensity = 0\`), which
  sees a clipped sun: before it, the predicted sun held about a quarter of the light it should
  (docs/RESULTS.md), and inserted objects cast faint shadows. On the sunny LDR crops, which have no
  energy label, \`loss.ldr_sun_energy\` keeps the energy inside the labelled span (\`release_sun_ldr.json\`).
- The mix per step: stage 2 and 2b draw 20% HDR crops, 20% LDR crops and 60% streets; the LDR energy
  step 10%, 10% and 80%; the last step streets alone.
- The sun direction is supervised only where the sun is hard (data/panorama_sample.h: ≥ 25% of the
  panorama's light within 5° of its peak, above the horizon) or, for an LDR panorama, labelled with a
  position.

## Training (configs, steps, wall time on this machine)
| step | config | steps | wall time |
|---|---|---|---|
| synthetic streets | \`configs/release_datagen.json\` | $(samples datagen) samples | $(secs datagen) s |
| held-out test streets | \`configs/release_datagen_test.json\` | $(samples datagen_test) samples | $(secs test_streets) s |
| stage 1, sky autoencoder | \`configs/release_sky.json\` | $(steps sky) | $(secs sky) s |
| stage 2, lighting | \`configs/release_lighting.json\` | $(steps lighting) | $(secs lighting) s |
| stage 2b, sun energy (from stage 2) | \`configs/release_sun.json\` | $(steps sun) | $(secs sun) s |
| LDR energy span (from 2b) | \`configs/release_sun_ldr.json\` | $(steps sun_ldr) | $(secs sun_ldr) s |
| streets (from the LDR energy span) | \`configs/release_streets.json\` | $(steps streets) | $(secs streets) s |
| evaluation | \`streetlight-eval\` (below) | | $(secs eval) s |
| **total** | | | **$total s** |

Reproduce: \`bash scripts/train_release.sh\` (resumable; \`--runs DIR\` for the run folder). Wall times
were measured while other jobs shared the machine unless the closing note of the release says otherwise.
The release configs pin what this model was trained with, even where later defaults changed:
\`model.volume.spacing = "metric"\`.

## Metrics (test splits, never trained or selected on)
Command: \`streetlight-eval --data ../shared/data/hdri --hdri-split configs/hdri_split.json --split test
--crops 8 --data ../shared/data/pano_ldr --ldr-split configs/pano_ldr_split.json --data RUN/test_street --baseline-data RUN/street
--no-budgets --checkpoint RUN/sun_ldr/best.safetensors --checkpoint RUN/streets/best.safetensors\`. The generated test streets are a separate set
(\`configs/release_datagen_test.json\`: its own seed, same generator settings), never trained or
selected on; the constant baseline comes from the training streets. Each image's sun is the
average of the network's answer for the image and for its mirror image (the estimator's default;
\`--no-flip-average\` gives one pass).
Sun errors in degrees. The constant baseline always answers the mean sun direction of the training
panoramas' crops (in the camera's frame); a model that does not beat it has learned nothing.

$(cat "$runs/eval/results.md")

## Known limits
- Its real data are $n_train HDR and $l_train LDR panoramas, beside $(samples datagen) synthetic streets: far less than
  the paper's HoliCity crops. Expect errors on skies unlike these (night, heavy overcast, snow).
- Where the sun is soft (overcast), the sun direction has no meaning and was not supervised.
$depth_limit
- Sizes are the CPU-scale defaults (dome 32×128, input 128×256, VSG 64×64×16), not the paper's.
EOF
