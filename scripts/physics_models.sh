#!/usr/bin/env bash
# The committed salsa set fine-tuned with the physics terms, each term ablated
# first. On the CPU, every step resumable (rerun the script to go on after a kill):
#
#   bash scripts/physics_models.sh                 # the ablation, then stop
#   GEN=g-mbc MOTION=m-mf bash scripts/physics_models.sh   # ... and the chosen pair, packaged
#
# 1. The salsa data (about 2 h 15 min of both cores; docs/use/DATASET.md), as
#    scripts/salsa_models.sh simulates it.
# 2. The generative model fine-tuned from the committed generative.pt on it (GEN_EPOCHS
#    epochs at GEN_LR), four runs, two side by side on one thread each:
#      g-plain  the paper's terms only (what the new data and the epochs alone do)
#      g-m      + membrane (edge lengths against rest)
#      g-mb     + membrane + bending
#      g-mbc    + membrane + bending + collision (the whole body as an obstacle)
#      g-m3x-bc the same with three times the membrane and bending weights
#    (weights: docs/design/notes/PHYSICS_PROBE.md, the probe on one clip, scripts/physics_probe.sh)
# 3. The motion stage fine-tuned from the committed motion.pt (mirrored clips, as the
#    committed ps-mirror run) on the generative run GEN_ABLATION (default g-mbc), three runs:
#      m-plain  the paper's terms only;  m-m  + membrane;  m-mf  + membrane + hem flare
# 4. bench/ablations/physics_ablation.py: every run on the account's clips (docs/results/PHYSICS_ABLATION.md).
# 5. With GEN and MOTION set (the runs the table chose): the detail stage fine-tuned from
#    the committed detail.pt on that motion stage, and the three packaged into
#    checkpoints/salsa (the set before is kept in out/salsa-without-physics-terms for the account's
#    "today" rows).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
BVH=${BVH:-../shared/mocap/cmu-salsa}
DATA=${DATA:-datasets/salsa}
RUNS=${RUNS:-runs/physics}
BASE=${BASE:-checkpoints/salsa}
GEN_EPOCHS=${GEN_EPOCHS:-6}
GEN_LR=${GEN_LR:-3e-4}
MOTION_EPOCHS=${MOTION_EPOCHS:-6}
MOTION_LR=${MOTION_LR:-3e-4}
DETAIL_EPOCHS=${DETAIL_EPOCHS:-4}
MEMBRANE=${MEMBRANE:-1000}
BENDING=${BENDING:-10}
COLLISION=${COLLISION:-30}
FLARE=${FLARE:-1}
GEN_ABLATION=${GEN_ABLATION:-g-mbc}
mkdir -p "$RUNS" out

# 1. the data
"$BIN/loosefit" simulate --preset salsa --bvh "$BVH" --out "$DATA" --workers 2

# the set before the physics terms (the one every run starts from, and the account's "today"
# rows), from the repository's history: the shipped set is the retrained one since
BEFORE=out/salsa-without-physics-terms
bash scripts/set_without_physics_terms.sh "$BEFORE"

done_run() {  # a run whose report is written is finished: not evaluated again
  [ -f "$RUNS/$1/report.json" ] && echo "[physics_models] $1: done ($RUNS/$1/report.json)"
}
gen() {  # name, extra flags
  local name=$1; shift
  done_run "$name" && return
  "$BIN/loosefit" train generative --data "$DATA" --preset cpu --epochs "$GEN_EPOCHS" \
      --lr "$GEN_LR" --init "$BEFORE/generative.pt" --threads 1 "$@" \
      --out "$RUNS/$name" > "$RUNS/$name.log" 2>&1
}
motion() {  # name, generative run, extra flags
  local name=$1 g=$2; shift 2
  done_run "$name" && return
  "$BIN/loosefit" train motion --data "$DATA" --preset cpu --epochs "$MOTION_EPOCHS" \
      --lr "$MOTION_LR" --mirror --generative "$RUNS/$g/checkpoint.pt" \
      --init "$BEFORE/motion.pt" --threads 1 "$@" --out "$RUNS/$name" > "$RUNS/$name.log" 2>&1
}

pair() {  # two commands (strings of words) side by side; fails if either fails
  $1 & local a=$!
  $2 & local b=$!
  wait "$a"; wait "$b"
}

# 2. generative, two at a time
pair "gen g-plain" "gen g-m --membrane $MEMBRANE"
pair "gen g-mb --membrane $MEMBRANE --bending $BENDING" \
     "gen g-mbc --membrane $MEMBRANE --bending $BENDING --collision $COLLISION"
gen g-m3x-bc --membrane $((3 * MEMBRANE)) --bending $((3 * BENDING)) --collision "$COLLISION"

# 3. motion on the ablation's generative run
pair "motion m-plain $GEN_ABLATION" "motion m-m $GEN_ABLATION --membrane $MEMBRANE"
motion m-mf "$GEN_ABLATION" --membrane "$MEMBRANE" --flare "$FLARE"

# 4. the table (once: the chosen pair's run below does not make it again)
[ -n "${GEN:-}" ] && [ -f bench/figures/PHYSICS_ABLATION.json ] ||
"$BIN/python" bench/ablations/physics_ablation.py --base "$BEFORE/motion.pt" \
    --generative g-before="$BEFORE/generative.pt" g-plain="$RUNS/g-plain/checkpoint.pt" \
    g-m="$RUNS/g-m/checkpoint.pt" g-mb="$RUNS/g-mb/checkpoint.pt" \
    g-mbc="$RUNS/g-mbc/checkpoint.pt" g-m3x-bc="$RUNS/g-m3x-bc/checkpoint.pt" \
    --motion m-before="$BEFORE/motion.pt" m-plain="$RUNS/m-plain/model.pt" \
    m-m="$RUNS/m-m/model.pt" m-mf="$RUNS/m-mf/model.pt" \
    --out docs/results/PHYSICS_ABLATION.md

# 5. the chosen pair, its detail stage, packaged
if [ -n "${GEN:-}" ] && [ -n "${MOTION:-}" ]; then
  [ "$GEN" = "$GEN_ABLATION" ] || motion "$MOTION-final" "$GEN" ${MOTION_FLAGS:-}
  M="$RUNS/$MOTION/model.pt"
  [ "$GEN" = "$GEN_ABLATION" ] || M="$RUNS/$MOTION-final/model.pt"
  D="detail-$GEN-$MOTION"  # one detail run per pair: another pair never reuses it
  done_run "$D" ||
  "$BIN/loosefit" train detail --data "$DATA" --preset cpu --epochs "$DETAIL_EPOCHS" \
      --motion "$M" --init "$BEFORE/detail.pt" --out "$RUNS/$D" > "$RUNS/$D.log" 2>&1
  "$BIN/loosefit" package "$M" --detail "$RUNS/$D/model.pt" --out "$BASE"
fi
