#!/usr/bin/env bash
# The committed salsa checkpoints (checkpoints/salsa) and docs/results/MOTION_TABLE.md, from scratch,
# on the CPU. Every step resumes where a killed run stopped; rerun the script to go on.
#
#   bash scripts/salsa_models.sh            # BVH clips from ../shared/mocap/cmu-salsa
#   BVH=/path/to/cmu-salsa bash scripts/salsa_models.sh
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
BVH=${BVH:-../shared/mocap/cmu-salsa}
DATA=${DATA:-datasets/salsa}
RUNS=${RUNS:-runs/salsa}
GEN_EPOCHS=${GEN_EPOCHS:-40}
MOTION_EPOCHS=${MOTION_EPOCHS:-40}

# 1. Ground truth: 10 training clips and the chained held-out sequence.
"$BIN/loosefit" simulate --preset salsa --bvh "$BVH" --out "$DATA" --workers 2
#    More simulated data for two rows of Table 1: the training clips also played 1.25 times as
#    fast; the clips salsa already has are taken from it, not simulated again (about 70 min).
#    And at 1.5 times as fast too (about 70 min more).
DATASETS=$(dirname "$DATA")
"$BIN/loosefit" simulate --preset salsa-speed --bvh "$BVH" --out "$DATASETS/salsa-speed" \
    --workers 2 --reuse "$DATA"
"$BIN/loosefit" simulate --preset salsa-speeds --bvh "$BVH" --out "$DATASETS/salsa-speeds" \
    --workers 2 --reuse "$DATASETS/salsa-speed"
# 2. The generative model (paper 3.2), CPU configuration; salsa has 13x the frames of demo,
#    so fewer epochs give the same number of steps.
"$BIN/loosefit" train generative --data "$DATA" --preset cpu --epochs "$GEN_EPOCHS" \
    --out "$RUNS/generative"
mkdir -p "$RUNS/motion"
# 3. The motion encoder with and without the previous state, and the runs that test how the
#    previous state is trained (teacher forcing only, with noise, unrolled, a floor under
#    scheduled sampling, mirrored clips, twice the epochs, the spine and leg joints only,
#    a second seed, the faster clips): the runs of bench/ablations/motion_runs.yaml, one thread each, three side by side;
#    then Table 1 (paper 3.3, 4.3) from all of them, with the rest drape carried by the
#    root (no dynamics) and the generative model's own code of the simulation (the floor)
#    as reference rows.
ABL=("$BIN/python" bench/ablations/motion_ablation.py --data "$DATA" --datasets "$DATASETS" --preset cpu
     --generative "$RUNS/generative/checkpoint.pt" --epochs "$MOTION_EPOCHS" --out "$RUNS/motion")
ALL=ps,nops,ps-teacher,ps-teacher-noise,ps-unroll,ps-floor,ps-mirror,nops-mirror,nops-80,ps-floor-80
ALL=$ALL,ps-mirror-lower,nops-mirror-lower,ps-mirror-s1,ps-mirror-lower-s1,ps-mirror-speed
ALL=$ALL,ps-mirror-speeds
IFS=, read -ra runs <<< "$ALL"
for ((i = 0; i < ${#runs[@]}; i += 3)); do
  pids=()
  for run in "${runs[@]:i:3}"; do
    "${ABL[@]}" --runs "$run" --threads 1 --no-table > "$RUNS/motion/$run.log" 2>&1 & pids+=($!)
  done
  for pid in "${pids[@]}"; do wait "$pid"; done
done
"${ABL[@]}" --runs "$ALL" --table docs/results/MOTION_TABLE.md
#    Drift on the same frames: rollouts restarted from the simulation every N frames against
#    one unbroken rollout (Table 1's iter-N also changes which frames are scored).
"$BIN/python" bench/quality/motion_drift.py --data "$DATA" --runs "$RUNS/motion" --only "$ALL" \
    --table docs/results/MOTION_DRIFT.md
# 4. The shared pair (the ps run on mirrored clips): half precision, the motion stage
#    pointing at the generative one beside it.
"$BIN/loosefit" package "$RUNS/motion/ps-mirror/model.pt" --out checkpoints/salsa
# 5. The committed pair on the held-out takes, chained (never seen in training), 1,957 frames,
#    rendered to look at.
"$BIN/loosefit" animate checkpoints/salsa/motion.pt \
    "$BVH/60_03.bvh+$BVH/60_07.bvh+$BVH/61_03.bvh+$BVH/61_07.bvh" \
    --start-frame 10 --out out/salsa-heldout --render --png-every 100
# 6. The figures docs/design/MOTION.md cites for the committed pair: error by stretch of motion, edge
#    strain, vertices inside the body.
"$BIN/python" bench/quality/motion_quality.py --checkpoint checkpoints/salsa/motion.pt --data "$DATA"
# 7. The detail module (paper 3.4) on the committed motion stage's own rollouts of the
#    training clips: with and without the multi-scale discriminator (Table 2's rows) and
#    with an edge-length term added to Eq. 13 (for the edge-strain target), one core
#    each; the full one joins the committed set; Table 2 with collision handling, the
#    renders of the held-out spin and the pipeline's speed against the simulation.
mkdir -p "$RUNS/detail"
pids=()
for kind in full nodisc full-edge; do
  flag=()
  [ "$kind" = nodisc ] && flag=(--no-discriminator)
  [ "$kind" = full-edge ] && flag=(--edge-weight 10)
  "$BIN/loosefit" train detail --data "$DATA" --preset cpu --motion checkpoints/salsa/motion.pt \
      --threads 1 "${flag[@]}" --out "$RUNS/detail/$kind" > "$RUNS/detail/$kind.log" 2>&1 &
  pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done
"$BIN/loosefit" package checkpoints/salsa/motion.pt --detail "$RUNS/detail/full/model.pt" \
    --out checkpoints/salsa
"$BIN/python" bench/ablations/detail_collision.py --data "$DATA" --detail "$RUNS/detail/full/model.pt" \
    --detail-nodisc "$RUNS/detail/nodisc/model.pt" --detail-edge "$RUNS/detail/full-edge/model.pt" \
    --out docs/results/DETAIL_TABLE.md
"$BIN/python" bench/quality/detail_renders.py --data "$DATA" --out docs/img/detail_spin.jpg
"$BIN/python" bench/quality/detail_renders.py --data "$DATA" --close --out docs/img/detail_spin_hips.jpg
"$BIN/python" bench/speed/rollout_speed.py --cloth-from "$DATA" --out out/bench-pipeline-salsa.json
