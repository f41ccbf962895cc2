#!/usr/bin/env bash
# reference_outputs.sh OUT_DIR [CODE_DIR]: make the outputs that a behaviour-preserving change must
# leave equal, with the code of CODE_DIR (default: this checkout). Compare two such folders with
#   python scripts/compare_runs.py h5 BEFORE/dsA AFTER/dsA     (and dsB)
#   python scripts/compare_runs.py ckpt BEFORE/trainA/best.pt AFTER/trainA/best.pt   (last.pt, B)
#   python scripts/compare_runs.py results BEFORE/evalA/r/results.json AFTER/evalA/r/results.json
# A: the Blender dataset of 8 models, one epoch of PCNBV (fold 1: the 8 models are airplanes and
#    cabinets), the evaluation of its test split by every method without a network (2 models a
#    dataset: the networks chose their checkpoints on models of these names, so the evaluator
#    would leave them out).
# B: a ray-cast dataset of every category, one epoch of PCNBV-sph, both networks evaluated on 2
#    unseen models; that evaluation exported in PC-NBV's layout (exportB).
# planA: `nbv.plan` on a mesh of ../shared/meshes (ig, 4 views, 2 captures saved), when the folder
#    exists. About 12 minutes on 2 cores. Compare those with
#   python scripts/compare_runs.py files BEFORE/exportB AFTER/exportB   (every file, byte for byte)
#   python scripts/compare_runs.py plan BEFORE/planA/plan.json AFTER/planA/plan.json
set -euo pipefail
OUT=$(realpath -m "$1")
CODE=$(realpath "${2:-$(dirname "$0")/..}")
PY=${PYTHON:-$CODE/.venv/bin/python}
cd "$CODE"
export PYTHONPATH="$CODE"
mkdir -p "$OUT"
step() {  # step NAME COMMAND...: run, log to OUT/NAME.log, report seconds
  local name=$1 t0=$SECONDS; shift
  "$@" > "$OUT/$name.log" 2>&1 || { echo "$name failed: see $OUT/$name.log" >&2; exit 1; }
  echo "$name $((SECONDS - t0)) s"
}
step dsA $PY -m nbv.dataset limit=8 out_dir="$OUT/dsA" progress=false hydra.run.dir="$OUT/hydra/dsA"
step trainA $PY -m train dataset="$OUT/dsA" fold=1 epochs=1 eval_every=1 out_dir="$OUT/trainA" \
  progress=false
step evalA $PY -m nbv.eval data_dir="$OUT/dsA" dataset=test limit=2 out_root="$OUT/evalA" run=r \
  'methods=[random,spread,oracle,hull_sco,hull_sco_sph,hull_sco_probes,hull_sco_replan,ig,hull_ig,ig_learned]' \
  plots=false progress=false
step dsB $PY -m nbv.dataset renderer.backend=raycast \
  'synthetic.counts={train: 1, valid: 1, test: 0, unseen: 1}' out_dir="$OUT/dsB" progress=false \
  hydra.run.dir="$OUT/hydra/dsB"
step trainB $PY -m train dataset="$OUT/dsB" epochs=1 eval_every=1 model=pcnbv_sph \
  out_dir="$OUT/trainB" progress=false
step evalB $PY -m nbv.eval data_dir="$OUT/dsB" limit=2 out_root="$OUT/evalB" run=r \
  checkpoints.pcnbv="$OUT/trainA/best.pt" checkpoints.pcnbv_sph="$OUT/trainB/best.pt" \
  plots=false progress=false
step exportB $PY -m nbv.export eval_run="$OUT/evalB/r" out_dir="$OUT/exportB" progress=false
MESH="$CODE/../shared/meshes/suzanne.obj"
if [ -f "$MESH" ]; then
  step planA $PY -m nbv.plan mesh="$MESH" method=ig n_views=4 save_captures=2 page=false \
    out_dir="$OUT/planA"
fi
