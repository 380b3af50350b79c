#!/usr/bin/env bash
# The arrays a change of the house's layout must leave bit for bit equal: the demo's
# sequence, a short training run's checkpoints (generative and motion), a short
# simulation. Run it before and after, then compare:
#   bash scripts/same_outputs.sh /tmp/before   (on the old commit)
#   bash scripts/same_outputs.sh /tmp/after    (on the new one)
#   python scripts/same_outputs.py /tmp/before /tmp/after
# Needs the dance corpus unpacked in datasets/dance (../shared/datasets/README.md).
set -euo pipefail
out=${1:?usage: same_outputs.sh OUT_FOLDER}
data=${DATA:-datasets/dance}
bin=${LOOSEFIT:-.venv/bin/loosefit}
rm -rf "$out" && mkdir -p "$out"
export OMP_NUM_THREADS=1
$bin demo --out "$out/demo" --threads 1
$bin simulate --preset tiny --max-frames 6 --workers 1 --out "$out/simulate"
$bin train generative --data "$data" --epochs 1 --max-frames 12 --threads 1 --seed 0 \
    --out "$out/generative"
$bin train motion --data "$data" --generative "$out/generative/checkpoint.pt" --epochs 1 \
    --max-frames 12 --threads 1 --seed 0 --out "$out/motion"
$bin train engine --data "$data" --motion "$out/motion/model.pt" --basis 8 --epochs 1 \
    --max-frames 12 --threads 1 --seed 0 --out "$out/engine"
