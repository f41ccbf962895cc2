#!/usr/bin/env bash
# PCNBV's full schedule on one NVIDIA GPU (issue 41), in at most BUDGET_S seconds (default 690,
# under 12 minutes): (1) the CUDA test, (2) the large training dataset (conf/dataset_large.yaml,
# ray cast, 8 shards in parallel on all cores) when data/generated/large lacks a shard's samples,
# (3) PCNBV trained on every category (fold=-1) on coverage and on VIG at once, with the
# authors' schedule (30 epochs, lr 1e-4 times 0.95 every epoch, batch 21), (4) the numbers.
#
# Run from the repository root, on a machine with the GPU and no internet:
#   bash scripts/gpu_schedule.sh            # PYTHON=/path/to/python to choose the interpreter
# Every step resumes: a shard's finished models are kept (.parts-*), training continues from its
# last.pt (outputs/train/large_pcnbv_<score>_all/; DATA and RUNS name other folders). A step cut
# off by the budget goes on at the next run; training starts only once all 8 shards have their
# samples (a dataset that grows would change the runs' identity and stop their resumption).
#
# Through the device tool: run(command="BUDGET_S=560 bash scripts/gpu_schedule.sh",
# timeout_s=600), since a command there runs 10 minutes at most. Its machine is bare and each call
# starts afresh (an earlier call's dataset and checkpoints are gone). Its python3 holds torch with
# CUDA but not all the project's packages: hydra-core, omegaconf, antlr4-python3-runtime, fpsample
# and trimesh travel as wheels in .whl/ (carry: [".whl"]; installed below when the folder exists);
# open3d, which ray casts the dataset and the CUDA test's data, does not (open3d-cpu 0.20.0's wheel
# is 105 MB, over the 64 MiB a call carries), so there the script stops at its package check.
#
# Writes to $OUT when set, else outputs/gpu/: summary.txt (each step's status and seconds, the
# GPU, each run's last metrics.csv rows, samples per second and best.pt's validation AUC),
# cuda_test.log, dataset.log, train_coverage.log, train_vig.log, metrics_coverage.csv,
# metrics_vig.csv. Exit status 0 when every step that ran succeeded.
set -euo pipefail

BUDGET_S=${BUDGET_S:-690}
TRAIN_RESERVE_S=${TRAIN_RESERVE_S:-240}  # kept for training when the dataset is generated
FINISH_RESERVE_S=${FINISH_RESERVE_S:-30}  # kept for writing the numbers
DATA=${DATA:-data/generated/large}    # the dataset folder (conf/dataset_large.yaml's)
RUNS=${RUNS:-outputs/train}           # the training runs go to $RUNS/large_pcnbv_<score>_all
SHARDS=8
DEADLINE=$(($(date +%s) + BUDGET_S))
RESULTS=${OUT:-outputs/gpu}
mkdir -p "$RESULTS"
SUMMARY=$RESULTS/summary.txt
: >"$SUMMARY"
STATUS=0

say() { echo "$*" | tee -a "$SUMMARY"; }
left() { echo $((DEADLINE - $(date +%s))); }
step() { # step NAME SECONDS LOG COMMAND...: COMMAND under timeout into LOG; returns its status
  local name=$1 limit=$2 log=$3 t0=$SECONDS rc=0
  shift 3
  if ((limit < 1)); then
    say "$name: skipped, no time left"
    return 1
  fi
  timeout --kill-after=20 "$limit" "$@" >"$log" 2>&1 || rc=$?
  say "$name: exit $rc after $((SECONDS - t0)) s (limit $limit s; 124 = cut off; log $log)"
  return "$rc"
}

if [[ -d .whl ]]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl
  export PYTHONPATH=/tmp/site
fi
if [[ -z ${PYTHON:-} ]]; then
  PYTHON=python3
  [[ -x .venv/bin/python ]] && PYTHON=.venv/bin/python
fi
if ! "$PYTHON" -c 'import torch; assert torch.cuda.is_available()' 2>/dev/null; then
  say "no CUDA device for $PYTHON (torch missing, a CPU build, or no GPU): nothing run"
  exit 2
fi
needs='import pytest, open3d, train.__main__, train.loop, nbv.dataset.generator'
if ! missing=$("$PYTHON" -c "$needs" 2>&1); then
  say "$PYTHON lacks the project's packages: ${missing##*$'\n'}; nothing run"
  exit 2
fi
export PYTHONUNBUFFERED=1
say "python: $PYTHON; budget $BUDGET_S s; $(nproc) cores"
say "$(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader)"

# (1) The CUDA test.
step "cuda test" "$(($(left) < 240 ? $(left) : 240))" "$RESULTS/cuda_test.log" \
  "$PYTHON" -m pytest -q -p no:cacheprovider tests/test_train.py -k cuda || STATUS=1

# (2) The dataset: every shard at once, 2 ray-casting threads each, until TRAIN_RESERVE_S is left.
samples() { find "$DATA" -maxdepth 1 -name 'samples-shard-*.h5' 2>/dev/null | wc -l; }
cap=$(($(left) - TRAIN_RESERVE_S))
if (($(samples) < SHARDS && cap > 0)); then
  t0=$SECONDS
  logs=$(mktemp -d)
  threads=$(($(nproc) / SHARDS > 1 ? $(nproc) / SHARDS : 1))
  for ((k = 0; k < SHARDS; k++)); do
    [[ -f $DATA/samples-shard-$(printf '%05d-of-%05d' $k $SHARDS).h5 ]] && continue
    timeout --kill-after=20 "$cap" "$PYTHON" -m nbv.dataset --config-name dataset_large \
      out_dir="$DATA" shard=$k renderer.threads=$threads progress=false \
      hydra.run.dir=outputs/dataset/large_shard$k >"$logs/shard$k.log" 2>&1 &
  done
  wait # a shard cut off by the cap resumes at the next run
  tail -n 3 "$logs"/shard*.log >"$RESULTS/dataset.log"
  say "dataset generation: $((SECONDS - t0)) s (cap $cap s; log $RESULTS/dataset.log)"
fi

# (3) Training, coverage and VIG side by side on the GPU, until FINISH_RESERVE_S is left.
say "dataset: $(samples) of $SHARDS shards with samples in $DATA"
if (($(samples) < SHARDS)); then
  say "training skipped until every shard has its samples: rerun to go on"
  STATUS=1
else
  limit=$(($(left) - FINISH_RESERVE_S))
  pids=()
  for score in coverage vig; do
    step "train $score" "$limit" "$RESULTS/train_$score.log" \
      "$PYTHON" -m train model=pcnbv fold=-1 dataset="$DATA" score=$score epochs=30 lr=1e-4 \
      lr_decay=0.95 lr_step_epochs=1 batch_size=21 device=cuda loader_workers=4 threads=8 \
      progress=false out_dir="$RUNS/large_pcnbv_${score}_all" &
    pids+=($!)
  done
  for pid in "${pids[@]}"; do wait "$pid" || STATUS=1; done
fi

# (4) The numbers.
say "$(nvidia-smi)"
for score in coverage vig; do
  run=$RUNS/large_pcnbv_${score}_all
  [[ -f $run/metrics.csv ]] || continue
  cp "$run/metrics.csv" "$RESULTS/metrics_$score.csv"
  say "== $score: $run/metrics.csv, last rows"
  say "$(head -n 1 "$run/metrics.csv"; tail -n +2 "$run/metrics.csv" | tail -n 3)"
  say "$("$PYTHON" - "$run" <<'EOF'
import csv, sys
from pathlib import Path

run = Path(sys.argv[1])
last = list(csv.DictReader(open(run / "metrics.csv")))[-1]
print(f"epoch {last['epoch']}: {float(last['samples_per_s']):.0f} training samples/s, "
      f"load fraction {float(last['load_fraction']):.2f}")
if (run / "best.pt").exists():
    from nbv.models.checkpoints import load_checkpoint
    _, extra = load_checkpoint(run / "best.pt")
    print(f"best.pt: epoch {extra['epoch'] + 1}, validation AUC {extra['metrics'].get('val_auc')}")
else:
    print("best.pt: none yet (no validation AUC computed)")
EOF
)"
done
exit $STATUS
