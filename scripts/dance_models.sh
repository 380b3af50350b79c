#!/usr/bin/env bash
# The committed dance set (checkpoints/dance) and the paper's claims measured on dance never
# seen (docs/results/RESULTS.md), from the simulated `dance` corpus, on the CPU. Every step resumes:
# a finished run is reused, a killed one goes on from its last checkpoint; rerun the script
# to go on after a kill or in the next session.
#
#   bash scripts/dance_models.sh                   # the data, both sets, the choice, results
#   STEPS=data,set bash scripts/dance_models.sh    # only some of the steps
#
# 1. data: the corpus, unpacked from ../shared/datasets (`loosefit dataset unpack`, about
#    10 s) when it is there, else simulated (`loosefit simulate --preset dance`, about 10
#    core-hours); a clip already in datasets/dance is never simulated again. The physical
#    reference: the held-out chain's first 300 frames and ballet 05_10 simulated again from
#    another seed (configs/reference_seed.yaml, about 20 CPU minutes).
# 2. set: two candidate sets on the corpus's training clips, one core each, side by side:
#    `ft`, the committed salsa set (checkpoints/salsa) fine-tuned (10 + 10 + 4 epochs), and
#    `scratch`, trained from nothing (30 + 30 + 4 epochs), both with the physics terms of
#    docs/results/PHYSICS_ABLATION.md (generative: membrane, bending, collision; motion: membrane,
#    hem flare, mirrored clips). bench/quality/compare_sets.py picks the one with the lowest RMSE on
#    the validation clips (simulated, left out of the split, never trained on; the held-out
#    clips never decide) among them and `ft` packaged without its detail stage, and it is
#    packaged into checkpoints/dance.
# 3. tables: Table 1 (the motion encoder with and without the previous state, the `scratch`
#    candidate's configuration on its generative stage: the with-state run is that
#    candidate's motion stage, 30 epochs, about 45 CPU minutes for the other) in
#    docs/results/MOTION_DANCE_TABLE.md, and Table 2 (the shipped candidate's detail stage and the
#    same training without its discriminator, 4 epochs, about 3 CPU minutes; each with and
#    without collision handling, per held-out clip, about 20 minutes) in
#    docs/results/DETAIL_DANCE_TABLE.md.
# 4. results: the generative ablation (Fig. 4, 20 epochs, two seeds), both baselines (two
#    seeds each) and every method on the held-out chain and the three held-out ballet
#    clips, with the physical reference row, and against the held-out clips' ensembles
#    (datasets/dance-seeds, unpacked from ../shared/datasets/dance-seeds.lfz, where it is
#    there): docs/results/RESULTS.md.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
SHARED=${SHARED:-../shared}
BVH=${BVH:-$SHARED/mocap/cmu-salsa}
DATA=${DATA:-datasets/dance}
REFERENCE=${REFERENCE:-datasets/dance-reference}
SEEDS=${SEEDS:-datasets/dance-seeds}  # the held-out clips from seeds 1-3 (dance-seeds.lfz)
RUNS=${RUNS:-runs/dance}
BASE=${BASE:-checkpoints/salsa}
SET=${SET:-checkpoints/dance}
STEPS=${STEPS:-data,set,tables,results}
LR=${LR:-3e-4}
export OMP_NUM_THREADS=1
mkdir -p "$RUNS"
step() { [[ ,$STEPS, == *,$1,* ]]; }

# 1. the data
if step data; then
  if [ ! -f "$DATA/manifest.json" ] && [ -f "$SHARED/datasets/dance.lfz.000" ]; then
    "$BIN/loosefit" dataset unpack "$SHARED/datasets/dance.lfz." "$DATA"
  elif [ ! -f "$DATA/manifest.json" ] || ! grep -q '"complete": true' "$DATA/manifest.json"; then
    "$BIN/loosefit" simulate --preset dance --bvh "$BVH" --out "$DATA" --workers 2
  fi
  "$BIN/loosefit" simulate --config configs/reference_seed.yaml --out "$REFERENCE" --workers 1 \
      > "$RUNS/reference.log" 2>&1
fi

chosen() {  # the set bench/quality/compare_sets.py chose (step set), by its candidate's name
  "$BIN/python" -c "import json; print(json.load(open('bench/figures/DANCE_SETS.json'))['winner'])"
}
done_run() {  # a run whose report is written is finished
  [ -f "$1/report.json" ] && echo "[dance_models] $1: done ($1/report.json)"
}
# one candidate set: generative, motion, detail, one thread; INIT: a set to start from or none
candidate() {
  local out=$1 gen_epochs=$2 motion_epochs=$3 init=$4 gen_init=() motion_init=() detail_init=()
  if [ "$init" != none ]; then
    gen_init=(--init "$init/generative.pt" --lr "$LR")
    motion_init=(--init "$init/motion.pt" --lr "$LR")
    detail_init=(--init "$init/detail.pt")
  fi
  mkdir -p "$out"
  done_run "$out/generative" ||
  "$BIN/loosefit" train generative --data "$DATA" --preset cpu --epochs "$gen_epochs" \
      "${gen_init[@]}" --membrane 1000 --bending 10 --collision 30 --threads 1 \
      --out "$out/generative" > "$out/generative.log" 2>&1
  done_run "$out/motion" ||
  "$BIN/loosefit" train motion --data "$DATA" --preset cpu --epochs "$motion_epochs" --mirror \
      --generative "$out/generative/checkpoint.pt" "${motion_init[@]}" --membrane 1000 \
      --flare 1 --threads 1 --out "$out/motion" > "$out/motion.log" 2>&1
  done_run "$out/detail" ||
  "$BIN/loosefit" train detail --data "$DATA" --preset cpu --epochs 4 \
      --motion "$out/motion/model.pt" "${detail_init[@]}" --threads 1 \
      --out "$out/detail" > "$out/detail.log" 2>&1
  "$BIN/loosefit" package "$out/motion/model.pt" --detail "$out/detail/model.pt" \
      --out "$out/set"
}
# 2. the two candidates (and the first without its detail stage), the choice, the committed set
if step set; then
  candidate "$RUNS/ft" 10 10 "$BASE" & ft=$!
  candidate "$RUNS/scratch" 30 30 none & scratch=$!
  wait "$ft" "$scratch"
  "$BIN/loosefit" package "$RUNS/ft/motion/model.pt" --out "$RUNS/ft-nodetail/set"
  "$BIN/python" bench/quality/compare_sets.py --data "$DATA" --cache "$RUNS/compare_sets" \
      --sets salsa="$BASE/motion.pt" ft="$RUNS/ft/set/motion.pt" \
      scratch="$RUNS/scratch/set/motion.pt" ft-nodetail="$RUNS/ft-nodetail/set/motion.pt" \
      --out docs/results/DANCE_SETS.md
  winner=$(chosen)
  [ "$winner" != salsa ] || { echo "[dance_models] the salsa set won: nothing to commit"; exit 1; }
  run=${winner%-nodetail} detail=(--detail "$RUNS/${winner%-nodetail}/detail/model.pt")
  [ "$winner" = "$run" ] || detail=()  # the winner is a candidate without its detail stage
  rm -rf "$SET.new"  # packaged beside, then put in place: a failed packaging leaves the old set
  "$BIN/loosefit" package "$RUNS/$run/motion/model.pt" "${detail[@]}" --out "$SET.new"
  rm -rf "$SET" && mv "$SET.new" "$SET"
fi
# 3. Tables 1 and 2 on dance
if step tables; then
  winner=$(chosen)
  winner=${winner%-nodetail}  # the candidate whose detail stage Table 2 measures
  mkdir -p "$RUNS/tables/motion-ablation"
  ln -sfn "$(realpath "$RUNS/scratch/motion")" "$RUNS/tables/motion-ablation/ps-physics"
  "$BIN/python" bench/ablations/motion_ablation.py --data "$DATA" --preset cpu --epochs 30 \
      --generative "$RUNS/scratch/generative/checkpoint.pt" --runs ps-physics,nops-physics \
      --threads 1 --out "$RUNS/tables/motion-ablation" --table docs/results/MOTION_DANCE_TABLE.md
  done_run "$RUNS/tables/detail-nodisc" ||
  "$BIN/loosefit" train detail --data "$DATA" --preset cpu --epochs 4 --no-discriminator \
      --motion "$RUNS/$winner/motion/model.pt" --init "$BASE/detail.pt" --threads 1 \
      --out "$RUNS/tables/detail-nodisc" > "$RUNS/tables/detail-nodisc.log" 2>&1
  "$BIN/python" bench/ablations/detail_collision.py --checkpoint "$RUNS/$winner/set/motion.pt" \
      --data "$DATA" --detail "$RUNS/$winner/detail/model.pt" \
      --detail-nodisc "$RUNS/tables/detail-nodisc/model.pt" --no-part-a \
      --out docs/results/DETAIL_DANCE_TABLE.md
fi
# 4. the paper's claims on dance
if step results; then
  winner=$(chosen)
  with_detail=""  # the shipped set without its detail stage: ours with it too, as a row
  [ "$winner" = "${winner%-nodetail}" ] || with_detail=$RUNS/${winner%-nodetail}/set/motion.pt
  members=""
  [ -d "$SEEDS" ] && members="$SEEDS/seed1 $SEEDS/seed2 $SEEDS/seed3"
  DATA=$DATA RUNS=$RUNS CHECKPOINT=$SET/motion.pt TABLE=docs/results/GENERATIVE_DANCE_TABLE.md \
      MEMBERS=$members ABLATION_EPOCHS=20 REFERENCE=$REFERENCE WITH_DETAIL=$with_detail \
      TABLE1=docs/results/MOTION_DANCE_TABLE.md TABLE2=docs/results/DETAIL_DANCE_TABLE.md bash scripts/results.sh
fi
