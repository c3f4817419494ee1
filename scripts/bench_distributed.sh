#!/usr/bin/env bash
# Data-parallel scaling on one machine (docs/DISTRIBUTED.md): the default lighting stage with
# 1 rank x 2 threads (batch 2) against 2 ranks x 1 thread (batch 1 each, the same global batch),
# and 1 rank x 1 thread for reference, as steps per second of stage.step() and the all-reduce's
# share of the step (mean, and the minimum over steps: the step where ranks waited least).
# Usage: scripts/bench_distributed.sh BUILD_DIR DATASET SKY_CKPT [STEPS]   (needs an MPI build)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,6p' "$0"; exit 0 ;; esac
if [ $# -lt 3 ]; then sed -n '2,6p' "$0" >&2; exit 2; fi
build=$(realpath -m "$1") data=$(realpath -m "$2") sky=$(realpath -m "$3") steps=${4:-20}
train=$build/tools/streetlight-train
[ -x "$train" ] || { echo "error: $train not found (build first)" >&2; exit 2; }
command -v mpirun > /dev/null || { echo "error: mpirun not found (scripts/install_deps.sh --mpi)" >&2; exit 2; }
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_mpi_yield_when_idle=1
sets=(--config configs/default_lighting.json --set init.sky_checkpoint="$sky" --set data.dataset="$data"
      --set train.steps="$steps" --set train.log_every=1 --set train.val_every=100000
      --set train.checkpoint_every=100000 --set train.image_every=100000 --set data.val_size=1 --json)
cd "$(dirname "$0")/.."
OMP_NUM_THREADS=1 "$train" "${sets[@]}" --set train.batch_size=2 --out "$out/single" > "$out/single.json" 2> /dev/null
OMP_NUM_THREADS=2 "$train" "${sets[@]}" --set train.batch_size=2 --out "$out/one" > "$out/one.json" 2> /dev/null
OMP_NUM_THREADS=1 mpirun -np 2 --bind-to none -x OMP_NUM_THREADS "$train" "${sets[@]}" --set train.batch_size=1 \
  --out "$out/two" > "$out/two.json" 2> /dev/null
/usr/bin/python3 - "$out" "$steps" <<'PY'
import json, sys
out, steps = sys.argv[1], int(sys.argv[2])
def summary(name):
    s = json.load(open(f"{out}/{name}.json"))
    lines = [json.loads(l) for l in open(f"{out}/{name}/metrics.jsonl")]
    train = [l for l in lines if l["split"] == "train"][2:]  # skip the first two steps (warm-up)
    step_ms = [sum(v for k, v in l.items() if k.startswith("time_")) for l in train]
    ar_ms = [l.get("time_allreduce_ms", 0.0) for l in train]
    phases = {k: round(sum(l[k] for l in train) / len(train), 1) for k in train[0] if k.startswith("time_")}
    return s["seconds_per_step"], sum(step_ms) / len(step_ms), sum(ar_ms) / len(ar_ms), phases, min(ar_ms)
s0, m0, _, p0, _ = summary("single")
s1, m1, _, p1, _ = summary("one")
s2, m2, a2, p2, amin = summary("two")
print(json.dumps({"steps": steps,
                  "one_rank_one_thread": {"steps_per_s": 1 / s0, "step_ms_after_warmup": m0, "phases_ms": p0},
                  "one_rank_two_threads": {"steps_per_s": 1 / s1, "step_ms_after_warmup": m1, "phases_ms": p1},
                  "two_ranks_one_thread": {"steps_per_s": 1 / s2, "step_ms_after_warmup": m2, "phases_ms": p2,
                                           "allreduce_ms": a2, "allreduce_share": a2 / m2,
                                           "allreduce_ms_min": amin, "allreduce_share_min": amin / m2},
                  "speed_ratio_two_ranks_over_one": s1 / s2}, indent=1))
PY
