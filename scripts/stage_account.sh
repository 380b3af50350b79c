#!/usr/bin/env bash
# The per-stage account (docs/results/STAGE_ACCOUNT.md), from scratch and resumable:
#   bash scripts/stage_account.sh        # about 70 CPU minutes on dev-cpu (2 cores)
# 1. ground truth of the spin and the three held-out ballet clips (bench/quality/account.yaml);
# 2. the held-out salsa chain's fastest spin (frames 1,140-1,260, settled and blended in at
#    1,140, as docs/use/DATASET.md simulates it);
# 3. every stage of the committed model measured against them, with renders.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=.venv/bin
"$BIN/loosefit" simulate --config bench/quality/account.yaml --out datasets/account
[ -f out/chain_spin.npz ] || "$BIN/python" bench/data/spin_substeps.py --save out/chain_spin.npz
bash scripts/set_without_physics_terms.sh out/salsa-without-physics-terms   # the "today" rows' set
B="--before out/salsa-without-physics-terms/motion.pt"
"$BIN/python" bench/quality/stage_account.py --data datasets/account --sequence out/chain_spin.npz $B
"$BIN/python" bench/quality/stage_renders.py --sequence out/chain_spin.npz --frames 48,60,72 $B \
    --out docs/img/stage_chain_spin.jpg
"$BIN/python" bench/quality/stage_renders.py --clip 05_10 --frames 85,99,110 $B \
    --out docs/img/stage_ballet_leg.jpg
"$BIN/python" bench/quality/stage_renders.py --clip 05_12 --frames 60,150,240 $B \
    --out docs/img/stage_ballet_arms.jpg
