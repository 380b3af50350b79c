#!/usr/bin/env bash
# The pretrained salsa set as shipped before its physics terms (commit be3b7ee), into
# a folder (default out/salsa-without-physics-terms): the runs of scripts/physics_models.sh start from
# it, and the stage account's "today" rows are its. Needs the repository's history.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/salsa-without-physics-terms}
[ -f "$OUT/motion.pt" ] && exit 0
mkdir -p "$OUT"
for f in generative motion detail; do
  git show "be3b7ee:src/loosefit/pretrained/salsa/$f.pt" > "$OUT/$f.pt.tmp"
  mv "$OUT/$f.pt.tmp" "$OUT/$f.pt"
done
echo "[set_without_physics_terms] the set before the physics terms in $OUT"
