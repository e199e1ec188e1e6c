#!/usr/bin/env bash
# Fits the sit to where the library's sitting controller hands the character over to it, then
# retrains the controller (stop 35; README "Stop 35" has the figures). Run it after
# `scripts/train-library.sh` and a first `repertoire meta train --library LIBRARY --iterations 2400`:
#   1. `meta deliver --spec sit_reach.ron --max-offset 0.8 --max-turn 90` plays the controller
#      (DELIVER_TRIALS episodes per zone, 200, seed 7) and keeps the states at which it switches
#      to sit, chair where it left it, in RUN/handovers.ron; a second delivery (seed 11, half as
#      many episodes) is held out for the evaluation, RUN/handovers-held.ron;
#   2. `skill finetune sit_reach.ron --from RUN/handovers.ron,stand --fraction 0.8` for
#      SIT_HANDOVER_ITERS (2000; 0 skips it), the critic warmed up for CRITIC_WARMUP iterations
#      first (100);
#   3. the sit evaluated from the clip start, from the stand's end poses (writing its pool) and
#      from the held-out handovers;
#   4. `meta train scenes/sit.ron --iterations META_ITERS` (2400; 0 skips both)
#      into LIBRARY/meta, then `meta eval --trials META_TRIALS` (1000 per zone).
# Usage: bash scripts/train-sit-handovers.sh [LIBRARY] — env: RUN (runs/sit-handovers), TRIALS
# (1000, the skill evaluations), EXTRA (more arguments for every finetune).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-skills/library}"
evals="$lib/evals.md"
run="${RUN:-runs/sit-handovers}"
deliver_trials="${DELIVER_TRIALS:-200}"
mkdir -p "$run"

deliver() {
  "$bin" meta deliver scenes/sit.ron --spec "$specs/sit_reach.ron" --library "$lib" \
    --max-offset 0.8 --max-turn 90 "$@"
}
deliver --trials "$deliver_trials" --seed 7 --out "$run/delivered.ron" --handovers-out "$run/handovers.ron"
deliver --trials $(((deliver_trials + 1) / 2)) --seed 11 --out "$run/delivered-held.ron" \
  --handovers-out "$run/handovers-held.ron"

if [ "${SIT_HANDOVER_ITERS:-2000}" != 0 ]; then
  "$bin" skill finetune "$specs/sit_reach.ron" --from "$run/handovers.ron,stand" --fraction 0.8 \
    --iterations "${SIT_HANDOVER_ITERS:-2000}" --critic-warmup "${CRITIC_WARMUP:-100}" --library "$lib" "${extra[@]}"
fi
eval_skill "$specs/sit.ron" --no-pool
eval_skill "$specs/sit.ron" --from stand
eval_skill "$specs/sit.ron" --from "$run/handovers-held.ron" --no-pool

if [ "${META_ITERS:-2400}" != 0 ]; then
  "$bin" meta train scenes/sit.ron --library "$lib" --iterations "${META_ITERS:-2400}" \
    --run-dir "$run/meta-train"
  "$bin" meta eval scenes/sit.ron --library "$lib" --trials "${META_TRIALS:-1000}"
fi
echo "sit fitted to the controller's handovers in $lib (evaluations appended to $evals)"
