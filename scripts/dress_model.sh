#!/usr/bin/env bash
# A dress, end to end on the CPU (docs/use/YOUR_GARMENT.md): simulate the `dress` preset, train
# both stages, animate a dance the model never saw, render it and export it to USD. Every
# step resumes where a killed run stopped; rerun the script to go on. Each step prints its
# time; docs/use/YOUR_GARMENT.md has the figures of dev-cpu (2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
DATA=${DATA:-datasets/dress}
RUNS=${RUNS:-runs/dress}
OUT=${OUT:-out/dress}
mkdir -p "$RUNS" "$OUT"

step() { local t0=$SECONDS; "$@"; echo "[dress_model] $(( SECONDS - t0 )) s: $*" | tee -a "$RUNS/times.txt"; }

# 0. A garment tool's export, imported: the parametric dress as an OBJ (metres, Z up), read
#    back with its units, axes and placement guessed
step "$BIN/loosefit" garment dress --out "$OUT/garment"
step "$BIN/loosefit" garment "$OUT/garment/dress.obj" --out "$OUT/imported"
# 1. Ground truth: the parametric dress with straps on 6 procedural dances of 4 s (one held out)
step "$BIN/loosefit" simulate --preset dress --out "$DATA" --workers 2
# 2. The garment generative model (paper 3.2), CPU configuration
step "$BIN/loosefit" train generative --data "$DATA" --preset cpu --out "$RUNS/generative"
# 3. The dynamic motion encoder (3.3) on the frozen generative model
step "$BIN/loosefit" train motion --data "$DATA" --preset cpu \
    --generative "$RUNS/generative/checkpoint.pt" --out "$RUNS/motion"
# 4. A shareable pair, then a 10 s dance it was not trained on (seed 7; the data's dances
#    are seeds 1000-1005), rendered and exported for a DCC tool
step "$BIN/loosefit" package "$RUNS/motion/model.pt" --out "$RUNS/package"
step "$BIN/loosefit" animate "$RUNS/package/motion.pt" dance:10 --seed 7 --out "$OUT/dance.npz" \
    --export "$OUT/dance.usdc" --render --views front,side,three_quarter
# 5. Its held-out clip against the simulation
step "$BIN/loosefit" evaluate --checkpoint "$RUNS/package/motion.pt" --data "$DATA" \
    --out "$RUNS/evaluate" --horizons 30,60,120
#    ... beside the drape carried rigidly and the generative model's floor
step "$BIN/python" bench/quality/rollout_references.py --checkpoint "$RUNS/package/motion.pt" \
    --data "$DATA" --out "$RUNS/references.json"
