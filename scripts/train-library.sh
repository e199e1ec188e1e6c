#!/usr/bin/env bash
# Trains the default skill library (walk, walk_to, turn_left, turn_right, the wide turns, stand, sit) from scratch and evaluates
# it: the shipped skills/library is this script's output, and every skill's manifest records
# the whole lineage (each stage's command, code version, figures and resulting policy hash).
# The sitting paper's two stages, along the skill graph walk → turn → walk / sit:
#   1. each skill from its spec with reference-state initialisation (kept as LIBRARY-stage1,
#      which the "no transition fine-tuning" ablation runs on);
#   2. transition fine-tuning from the predecessors' end-pose pools, which `skill eval` writes
#      (successful end states from the clip start; a cycle's pool keeps a state from a random
#      moment of each trial, and a cycle started from a pool state picks its clip up at the
#      nearest frame):
#        a. the turns from walk's states;
#        b. walk from the turns' end poses (the meta-controller walks on after a turn);
#        c. the turns again, from the fine-tuned walk's states;
#        d. sit from the turns' end poses, in three rounds: SIT_FINETUNE_ITERS with 70 % of the
#           episodes from the pools, then SIT_FINETUNE2_ITERS with 60 % (the rest keep
#           reference-state starts, so that sitting from a standing start is not forgotten),
#           then SIT_REACH_ITERS of `sit_reach.ron` (the chair jittered by up to 60 cm and 60°
#           instead of 25 cm and 20°, so the sit takes the character from further off), then
#           that spec again at 70 % for each of SIT_REACH_MORE_ITERS (two rounds of 2000: the
#           sit from the turns' end poses kept improving over both);
#        e. walk_to, the walk that steers towards a 2-D target (the sitting scenario's walk),
#           grown from the fine-tuned walk in three stages (WALK_TO_ITERS: 600 with the spread
#           raised to log std -2.2, then 1200 and 1200) and fine-tuned from the turns' end
#           poses (WALK_TO_FINETUNE_ITERS, 800); LIBRARY-stage1 gets walk_to grown the same
#           way from its own stage-one walk, without the fine-tune;
#        f. the wide (±99°) turns, `scripts/train-wide-turns.sh` (its own settings there);
#        g. the stand, and the sit fitted to it, `scripts/train-stand.sh` (its settings there);
#      the shipped sit then had one more round, from where a controller trained over this
#      library hands over to it (`scripts/train-sit-handovers.sh`, after `meta train`);
#   3. `skill eval` over TRIALS trials from the clip start and from the predecessors' end poses
#      after each stage; every table is also collected in LIBRARY/evals.md.
# Usage: bash scripts/train-library.sh [LIBRARY] — env: TRIALS (1000), TURN_FINETUNE_ITERS (400),
# WALK_FINETUNE_ITERS (800; 0 skips walk's fine-tune and the turns' second one),
# TURN_FINETUNE2_ITERS (400; 0 skips the turns' second fine-tune),
# SIT_FINETUNE_ITERS (600), SIT_FINETUNE2_ITERS (1000; 0 skips the second round),
# SIT_REACH_ITERS (1000; 0 skips the third), SIT_REACH_MORE_ITERS ("2000 2000"; "" skips them),
# WALK_TO_ITERS ("600 1200 1200"),
# WALK_TO_FINETUNE_ITERS (800),
# EXTRA (more arguments for every train/finetune, e.g. "--envs 8").
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-skills/library}"
mkdir -p "$lib"
evals="$lib/evals.md.partial"
printf '# Skill library evaluations\n\nWritten by `scripts/train-library.sh` (%s trials per row).\n' "$trials" > "$evals"
finetune() {
  "$bin" skill finetune "$@" --library "$lib" "${extra[@]}"
}
# walk_to grown from LIBRARY's walk (the first stage widens the walk's spread to explore turning).
grow_walk_to() {
  local l="$1" first=1
  for n in ${WALK_TO_ITERS:-600 1200 1200}; do
    if [ "$first" = 1 ]; then
      "$bin" skill train "$specs/walk_to.ron" --warm-start-from walk --explore-log-std -2.2 --iterations "$n" --library "$l" "${extra[@]}"
      first=0
    else
      "$bin" skill train "$specs/walk_to.ron" --warm-start --iterations "$n" --library "$l" "${extra[@]}"
    fi
  done
}

for s in walk turn_left turn_right sit; do
  "$bin" skill train "$specs/$s.ron" --library "$lib" "${extra[@]}"
done
rm -rf "$lib-stage1" && cp -r "$lib" "$lib-stage1" && rm -f "$lib-stage1/evals.md.partial"

eval_skill "$specs/walk.ron"
for s in turn_left turn_right; do
  finetune "$specs/$s.ron" --from walk --iterations "${TURN_FINETUNE_ITERS:-400}"
  eval_skill "$specs/$s.ron" --from walk
done
if [ "${WALK_FINETUNE_ITERS:-800}" != 0 ]; then
  finetune "$specs/walk.ron" --from turn_left,turn_right --fraction 0.7 --iterations "${WALK_FINETUNE_ITERS:-800}"
  eval_skill "$specs/walk.ron" --from turn_left,turn_right
  if [ "${TURN_FINETUNE2_ITERS:-400}" != 0 ]; then
    for s in turn_left turn_right; do
      finetune "$specs/$s.ron" --from walk --iterations "${TURN_FINETUNE2_ITERS:-400}"
      eval_skill "$specs/$s.ron" --from walk
    done
    # Walk from the turns' new end poses (its pool, from the clip start, stays as it is).
    eval_skill "$specs/walk.ron" --from turn_left,turn_right --no-pool
  fi
fi
finetune "$specs/sit.ron" --from turn_left,turn_right --fraction 0.7 --iterations "${SIT_FINETUNE_ITERS:-600}"
if [ "${SIT_FINETUNE2_ITERS:-1000}" != 0 ]; then
  finetune "$specs/sit.ron" --from turn_left,turn_right --fraction 0.6 --iterations "${SIT_FINETUNE2_ITERS:-1000}"
fi
if [ "${SIT_REACH_ITERS:-1000}" != 0 ]; then
  finetune "$specs/sit_reach.ron" --from turn_left,turn_right --fraction 0.6 --iterations "${SIT_REACH_ITERS:-1000}"
fi
for n in ${SIT_REACH_MORE_ITERS-2000 2000}; do
  finetune "$specs/sit_reach.ron" --from turn_left,turn_right --fraction 0.7 --iterations "$n"
done
eval_skill "$specs/sit.ron" --from turn_left,turn_right

grow_walk_to "$lib-stage1"
grow_walk_to "$lib"
finetune "$specs/walk_to.ron" --from turn_left,turn_right --fraction 0.7 --iterations "${WALK_TO_FINETUNE_ITERS:-800}"
eval_skill "$specs/walk_to.ron"
eval_skill "$specs/walk_to.ron" --from turn_left,turn_right --no-pool
mv "$evals" "$lib/evals.md"
# f. the wide (±99°) turns, fine-tuned from walk_to's end poses (and into LIBRARY-stage1).
bash scripts/train-wide-turns.sh "$lib"
# g. the stand between the turns and the sit, and the sit from its end poses.
bash scripts/train-stand.sh "$lib"
echo "library written to $lib (evaluations in $lib/evals.md)"
