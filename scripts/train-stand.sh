#!/usr/bin/env bash
# Adds the stand to a trained skill library and fits the sit to it (stop 34; the last stage of
# `scripts/train-library.sh`). The stand (`specs/stand.ron`) brings the character to rest from
# where walk_to and the four turns leave it, so the sit can start from the standing pose its clip
# starts from instead of mid-stride:
#   1. stand from its spec (STAND_ITERS, the spec's 800), 85 % of its episodes from walk_to's and
#      the turns' end poses, then fine-tuned the same way (STAND_FINETUNE_ITERS, 1200) with the
#      critic it saved; evaluated from the clip start and from those end poses, its pool taken
#      from the trials that started from them (`--pool-from predecessors`: from the clip start
#      the stand only stands, and every end state is the same);
#   2. `sit_reach.ron` fine-tuned from the stand's end poses and the 56° turns' (SIT_STAND_ITERS,
#      2000; 0 skips it; SIT_STAND_FRACTION of the episodes from the pools, 0.7), the critic
#      warmed up for 100 iterations first (the sit has no saved critic);
#   3. the sit evaluated from the stand's end poses (writing its pool, from the clip start) and
#      from the 56° turns'.
# Usage: bash scripts/train-stand.sh [LIBRARY] — env: TRIALS (1000), EXTRA (more arguments for
# every train/finetune). The library's meta-controllers pin every skill's weights, so retrain them
# afterwards (`repertoire meta train --library LIBRARY --iterations 2400`: the default scenes/sit.ron, stop 34),
# and then fit the sit to where that controller hands over (`scripts/train-sit-handovers.sh`, stop 35).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-skills/library}"
evals="$lib/evals.md"
preds=walk_to,turn_left,turn_right,turn_left_wide,turn_right_wide

iters=()
if [ -n "${STAND_ITERS:-}" ]; then iters=(--iterations "$STAND_ITERS"); fi
"$bin" skill train "$specs/stand.ron" --library "$lib" "${iters[@]}" "${extra[@]}"
"$bin" skill finetune "$specs/stand.ron" --from "$preds" --fraction 0.85 \
  --iterations "${STAND_FINETUNE_ITERS:-1200}" --library "$lib" "${extra[@]}"
eval_skill "$specs/stand.ron" --from "$preds" --pool-from predecessors
if [ "${SIT_STAND_ITERS:-2000}" != 0 ]; then
  "$bin" skill finetune "$specs/sit_reach.ron" --from stand,turn_left,turn_right \
    --fraction "${SIT_STAND_FRACTION:-0.7}" --iterations "${SIT_STAND_ITERS:-2000}" --critic-warmup 100 \
    --library "$lib" "${extra[@]}"
fi
eval_skill "$specs/sit.ron" --from stand
eval_skill "$specs/sit.ron" --from turn_left,turn_right --no-pool
echo "stand added to $lib (evaluations appended to $evals)"
