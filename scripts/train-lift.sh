#!/usr/bin/env bash
# Fits lift to the warehouse, then carry to the new lift, and evaluates both (README "Lift any
# box" has the figures):
#   1. `skill train lift.ron`: the keyframe clip, one 0.3 m, 2 kg box on a 0.57 m pedestal
#      exactly under the clip's hands (LIFT_ITERS, default 0: keep the library's lift, as stop
#      32's run did; 800 trains it afresh);
#   2. `skill finetune lift_any_box.ron --from walk,turn_left,turn_right`: the same skill, now
#      observing the box's size, on the warehouse's pedestals and boxes (0.45–0.75 m, ×0.75–1.25,
#      2–7 kg), the pedestal up to 0.25 m and ±45° off the clip's spot, gripping hands, half the
#      episodes from the locomotion skills' end poses, the critic warmed up first and a lower
#      learning rate (LIFT_BOXES_ITERS, 1200);
#   3. `skill eval lift_any_box.ron --from walk_to,turn_left,turn_right`, which writes lift's new
#      end-pose pool (the warehouse's CARRY and PUTDOWN starts);
#   4. carry's stage 5 again (`scripts/train-carry.sh`), now from the new lift's end poses, and its
#      evaluation (LIFT_CARRY_ITERS, 1200; 0 skips it).
# Usage: bash scripts/train-lift.sh [LIBRARY] — LIBRARY must hold walk, walk_to, the turns (with
# their end-pose pools) and carry; env: TRIALS (1000), EXTRA (more arguments for every train).
# Not yet in the library (stop 32): this run over the stop-31 library gave a lift that picks the
# box up from walk_to's arrivals 4× as often, but the warehouse controllers retrained over its
# carry stopped walking to the pedestal (README "Lift any box").
# A controller over a scenario that lists lift or carry pins their weights: retrain it afterwards.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-skills/library}"
evals="$lib/evals.md"

if [ "${LIFT_ITERS:-0}" -gt 0 ]; then
  "$bin" skill train "$specs/lift.ron" --iterations "${LIFT_ITERS}" --library "$lib" "${extra[@]}"
fi
"$bin" skill finetune "$specs/lift_any_box.ron" --from walk,turn_left,turn_right --fraction 0.5 \
  --iterations "${LIFT_BOXES_ITERS:-1200}" --critic-warmup 100 --learning-rate 0.0001 --library "$lib" "${extra[@]}"
eval_skill "$specs/lift_any_box.ron" --from walk_to,turn_left,turn_right
if [ "${LIFT_CARRY_ITERS:-1200}" -gt 0 ]; then
  "$bin" skill finetune "$specs/carry_any_box.ron" --from lift --fraction 0.5 --iterations "${LIFT_CARRY_ITERS:-1200}" \
    --critic-warmup 100 --learning-rate 0.0001 --library "$lib" "${extra[@]}"
  eval_skill "$specs/carry_any_box.ron" --from lift
fi
echo "lift and carry trained into $lib (evaluations appended to $evals)"
