#!/usr/bin/env bash
# Grows a second sit for the wide (±99°) turns from a library's sit (stop 26; README "Stop 26"
# has the figures):
#   1. `sit_from_wide.ron` from the library's sit (`--warm-start-from sit`), 80 % of its
#      episodes started from turn_left_wide's and turn_right_wide's end poses
#      (SIT_FROM_WIDE_ITERS, 1000);
#   2. a second round of the same (`--warm-start`, which continues the critic saved in round 1;
#      SIT_FROM_WIDE_MORE_ITERS, 1000; 0 skips it);
#   3. `skill eval` from the clip start and from the wide turns' end poses.
# Usage: bash scripts/train-sit-from-wide.sh [LIBRARY] — LIBRARY must hold sit and the wide
# turns with their pools; env: TRIALS (1000), EXTRA (more arguments for every train, e.g.
# "--envs 8"). The library's meta-controller pins its skills' weights: retrain it afterwards
# (`repertoire meta train --library LIBRARY --iterations 2400`).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-skills/library}"
evals="$lib/evals.md"

"$bin" skill train "$specs/sit_from_wide.ron" --warm-start-from sit --iterations "${SIT_FROM_WIDE_ITERS:-1000}" \
  --library "$lib" "${extra[@]}"
if [ "${SIT_FROM_WIDE_MORE_ITERS:-1000}" != 0 ]; then
  "$bin" skill train "$specs/sit_from_wide.ron" --warm-start --iterations "${SIT_FROM_WIDE_MORE_ITERS:-1000}" \
    --library "$lib" "${extra[@]}"
fi
eval_skill "$specs/sit_from_wide.ron" --from turn_left_wide,turn_right_wide --no-pool
echo "sit_from_wide trained into $lib (evaluations appended to $evals)"
