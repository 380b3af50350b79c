#!/usr/bin/env bash
# docs/results/RESULTS.md: the paper's baselines and the generative ablation on a data
# set (salsa; DATA=datasets/dance RUNS=runs/dance CHECKPOINT=... for dance), trained and
# compared with the committed model on its held-out clips, on the CPU; REFERENCE=DATASET adds
# the physical reference row (held-out motion simulated again from another seed);
# WITH_DETAIL=SET/motion.pt adds ours with a detail stage where the compared set has none;
# TABLE1, TABLE2: Markdown tables (bench/ablations/motion_ablation.py's, bench/ablations/detail_collision.py's)
# included as sections; MEMBERS="SEED1 SEED2 ...": data sets of the held-out clips simulated
# from other seeds, every method scored against them (bench/quality/ensemble.py, docs/results/ENSEMBLE.md) and
# that included as a section. Needs the
# data (scripts/salsa_models.sh step 1, scripts/dance_models.sh step 1) and the set it
# compares. Every step resumes where a killed run stopped (finished runs are reused); rerun
# the script to go on.
#
#   bash scripts/results.sh
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
DATA=${DATA:-datasets/salsa}
RUNS=${RUNS:-runs/salsa}
CHECKPOINT=${CHECKPOINT:-checkpoints/salsa/motion.pt}   # ours
TABLE=${TABLE:-docs/results/GENERATIVE_SALSA_TABLE.md}   # the ablation's own table
EPOCHS=${EPOCHS:-40}   # the committed generative and motion stages' epochs
ABLATION_EPOCHS=${ABLATION_EPOCHS:-$EPOCHS}   # the generative ablation's (each decoder's)
mkdir -p "$RUNS/baselines" "$RUNS/ablation"

# 1. The generative model's ablation (paper 4.2, Fig. 4) on salsa: the decomposed model, the
#    single vertex decoder and the linear decoder on a skinning decomposition, cpu preset, two
#    seeds each (the run-to-run noise); one thread per process, the two seeds side by side.
#    About 75 min per seed on one core of dev-cpu (decomposed 15 min, vertex 20, ssdr 40).
ABL=("$BIN/python" bench/ablations/generative_ablation.py --data "$DATA" --preset cpu --epochs "$ABLATION_EPOCHS"
     --out "$RUNS/ablation" --threads 1 --train-only)
"${ABL[@]}" --seeds 0 > "$RUNS/ablation/seed0.log" 2>&1 &
seed0=$!
"${ABL[@]}" --seeds 1 > "$RUNS/ablation/seed1.log" 2>&1 &
seed1=$!
# 2. The baselines, on the committed motion stage's data (the training clips and their mirror
#    images) for its 40 epochs, cpu preset, two seeds each (the second in METHOD-s1):
#    Santesteban et al. 2019 (5 min of training on one core) and Pan et al. 2022's virtual bones
#    (a Dem Bones decomposition of the 8,438 training frames, 4 min, then 15 min of training),
#    after the ablation's seeds; the two seeds side by side.
wait "$seed0" "$seed1"
baselines() {  # one seed of both baselines, one after the other
  local seed=$1 run
  for method in santesteban virtual-bones; do
    run="$RUNS/baselines/$method"
    [ "$seed" = 0 ] || run="$run-s$seed"
    [ -f "$run/report.json" ] && continue  # finished
    "$BIN/loosefit" train baseline --method "$method" --data "$DATA" --preset cpu --mirror \
        --epochs "$EPOCHS" --seed "$seed" --threads 1 --out "$run" > "$run.log" 2>&1
  done
}
baselines 0 & b0=$!
baselines 1 & b1=$!
wait "$b0" "$b1"
# 3. Every method rolled out on the held-out chain and scored, the ablation's table, the plot
#    and the renders: docs/results/RESULTS.md (about 15 min); with MEMBERS, every method against the
#    held-out clips' ensembles first (docs/results/ENSEMBLE.md, about 15 min).
"$BIN/python" bench/ablations/generative_ablation.py --data "$DATA" --preset cpu --epochs "$ABLATION_EPOCHS" \
    --seeds 0,1 --out "$RUNS/ablation" --table "$TABLE"
if [ -n "${MEMBERS:-}" ]; then
  # shellcheck disable=SC2086  # MEMBERS: data set folders, one word each
  "$BIN/python" bench/quality/ensemble.py --data "$DATA" --members $MEMBERS --checkpoint "$CHECKPOINT" \
      --baselines "$RUNS/baselines" --cache "$RUNS/ensemble" --out docs/results/ENSEMBLE.md
fi
"$BIN/python" bench/quality/results.py --data "$DATA" --checkpoint "$CHECKPOINT" \
    --baselines "$RUNS/baselines" --ablation "$RUNS/ablation" --cache "$RUNS/results" \
    ${REFERENCE:+--reference "$REFERENCE"} ${WITH_DETAIL:+--with-detail "$WITH_DETAIL"} \
    ${MEMBERS:+--ensemble docs/results/ENSEMBLE.md} ${TABLE1:+--table1 "$TABLE1"} ${TABLE2:+--table2 "$TABLE2"} --out docs/results/RESULTS.md
