#!/usr/bin/env bash
# A first probe of the physics terms' weights, on one simulated salsa clip (60_01,
# the first that datasets/salsa finishes), before the full ablation of
# scripts/physics_models.sh. The committed generative model fine-tuned on it for
# PROBE_EPOCHS epochs with each set of terms, one at a time on one thread, then measured by
# its own reconstruction of the account's held-out clips (bench/ablations/physics_ablation.py).
# Resumable; about 15 CPU minutes.
#
#   bash scripts/physics_probe.sh                    # both parts
#   PROBE_PART=motion bash scripts/physics_probe.sh  # the motion stage's part only
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
SALSA=${SALSA:-datasets/salsa}
VIEW=${VIEW:-datasets/probe-60_01}
RUNS=${RUNS:-runs/physics-probe}
EPOCHS=${PROBE_EPOCHS:-8}
LR=${PROBE_LR:-3e-4}
BASE=${BASE:-checkpoints/salsa}
[ -f out/salsa-without-physics-terms/generative.pt ] && BASE=out/salsa-without-physics-terms

# a data set of the one clip (links into datasets/salsa), trained and "tested" on it: the
# measure is the account's held-out clips
[ -f "$SALSA/sequences/60_01.npz" ] || { echo "$SALSA has not finished 60_01 yet"; exit 2; }
mkdir -p "$VIEW/sequences" "$RUNS"
ln -sf "$(realpath "$SALSA/template.npz")" "$VIEW/template.npz"
ln -sf "$(realpath "$SALSA/sequences/60_01.npz")" "$VIEW/sequences/60_01.npz"
"$BIN/python" - "$SALSA" "$VIEW" <<'EOF'
import json, sys
m = json.load(open(f"{sys.argv[1]}/manifest.json"))
m["split"] = {"train": ["60_01"], "test": ["60_01"]}
m["complete"] = True
m["sequences"] = {k: v for k, v in m["sequences"].items() if k == "60_01"}
json.dump(m, open(f"{sys.argv[2]}/manifest.json", "w"), indent=1)
EOF

PART=${PROBE_PART:-all}
gen() {  # name, flags
  local name=$1; shift
  "$BIN/loosefit" train generative --data "$VIEW" --preset cpu --epochs "$EPOCHS" --lr "$LR" \
      --init "$BASE/generative.pt" --threads 1 "$@" --out "$RUNS/$name" \
      > "$RUNS/$name.log" 2>&1
}
if [ "$PART" != motion ]; then
gen g-plain
gen g-m100 --membrane 100
gen g-m300 --membrane 300
gen g-m1000 --membrane 1000
gen g-m300-b10 --membrane 300 --bending 10
gen g-m300-b10-c30 --membrane 300 --bending 10 --collision 30
args=()
for r in g-plain g-m100 g-m300 g-m1000 g-m300-b10 g-m300-b10-c30; do
  args+=("$r=$RUNS/$r/checkpoint.pt")
done
"$BIN/python" bench/ablations/physics_ablation.py --base "$BASE/motion.pt" \
    --generative "g-before=$BASE/generative.pt" "${args[@]}" --out docs/design/notes/PHYSICS_PROBE.md
fi
[ "$PART" != gen ] || exit 0

# the motion stage on the one clip (mirrored too, as the committed ps-mirror run), fine-tuned
# from the committed motion.pt on the generative run PROBE_GEN, with and without the terms
PROBE_GEN=${PROBE_GEN:-g-m1000}
MEPOCHS=${PROBE_MOTION_EPOCHS:-4}
motion() {  # name, flags
  local name=$1; shift
  "$BIN/loosefit" train motion --data "$VIEW" --preset cpu --epochs "$MEPOCHS" --lr "$LR" \
      --mirror --generative "$RUNS/$PROBE_GEN/checkpoint.pt" --init "$BASE/motion.pt" \
      --threads 1 "$@" --out "$RUNS/$name" > "$RUNS/$name.log" 2>&1
}
motion m-plain
motion m-m1000 --membrane 1000
motion m-m1000-f1 --membrane 1000 --flare 1
"$BIN/python" bench/ablations/physics_ablation.py --base "$BASE/motion.pt" \
    --motion "m-before=$BASE/motion.pt" "m-plain=$RUNS/m-plain/model.pt" \
    "m-m1000=$RUNS/m-m1000/model.pt" "m-m1000-f1=$RUNS/m-m1000-f1/model.pt" \
    --out docs/design/notes/PHYSICS_PROBE_MOTION.md
