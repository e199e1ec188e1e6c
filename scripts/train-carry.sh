#!/usr/bin/env bash
# Grows carry from a library's walk in two stages, then evaluates it (stop 25; carry is not in
# the shipped library yet, README "Object skills" has the figures):
#   1. `carry_stage1.ron`: the walk with carry's arms held round a box at the chest and no box,
#      started from the library's walk (`--warm-start-from walk`; CARRY_ARMS_ITERS, 400);
#   2. `carry.ron --warm-start`: the same policy, its input grown for the box's pose (zero
#      weights), now with the box between its hands (CARRY_ITERS, 800);
#   3. `skill eval` from the clip start and from lift's end poses.
# A third round of stage 2 (1200 more iterations) made training episodes shorter, not longer
# (246 → about 130 steps), so there is none.
# Usage: bash scripts/train-carry.sh [LIBRARY] — LIBRARY must hold walk and lift; env: TRIALS
# (1000), EXTRA (more arguments for every train, e.g. "--envs 8"). Warehouse controllers pin
# their skills' weights: retrain them afterwards if the scenario lists carry.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-skills/library}"
evals="$lib/evals.md"

"$bin" skill train "$specs/carry_stage1.ron" --warm-start-from walk --iterations "${CARRY_ARMS_ITERS:-400}" \
  --library "$lib" "${extra[@]}"
"$bin" skill train "$specs/carry.ron" --warm-start --iterations "${CARRY_ITERS:-800}" --library "$lib" "${extra[@]}"
eval_skill "$specs/carry.ron" --from lift
echo "carry trained into $lib (evaluations appended to $evals)"
