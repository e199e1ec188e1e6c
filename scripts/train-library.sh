#!/usr/bin/env bash
# Trains the default skill library (walk, turn_left, turn_right, sit) from scratch, the way the
# shipped skills/library was made, and evaluates it (the sitting paper's two stages):
#   1. each skill from its spec with reference-state initialisation;
#   2. transition fine-tuning along the skill graph: the turns from walk's states, walk from the
#      turns' end poses (the meta-controller walks on after a turn), sit from the turns' end poses;
#   3. `skill eval` over TRIALS trials from the clip start and from predecessors' end poses
#      (which also writes each skill's end-pose pool, used by the next stage).
# The stage-one library is kept beside it as LIBRARY-stage1 (for the no-fine-tuning ablation).
# Sit is fine-tuned in two rounds: SIT_FINETUNE_ITERS (600) iterations with 70 % of the episodes
# from the turns' end poses, then SIT_FINETUNE2_ITERS (1000) more with 60 % (the rest keep
# reference-state starts, so that sitting from a standing start is not forgotten).
# Walk is a cycle: its pool holds a state from a random moment of each successful trial, and a
# walk started from a turn's end pose picks its cycle up at the nearest frame. Walk's pool is
# written before its own fine-tune (the turns were tuned from it) and kept after.
# Usage: bash scripts/train-library.sh [LIBRARY] — env: TRIALS (1000), TURN_FINETUNE_ITERS (400),
# WALK_FINETUNE_ITERS (800; 0 skips walk's fine-tune),
# SIT_FINETUNE_ITERS (600), SIT_FINETUNE2_ITERS (1000; 0 skips the second round),
# EXTRA (more arguments for every train/finetune, e.g. "--envs 8").
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
cargo build --release --quiet
bin="$root/target/release/repertoire"
lib="${1:-skills/library}"
trials="${TRIALS:-1000}"
extra=(${EXTRA:-})
specs=skills/skill/specs

for s in walk turn_left turn_right sit; do
  "$bin" skill train "$specs/$s.ron" --library "$lib" "${extra[@]}"
done
# Keep the stage-one library: the "no transition fine-tuning" ablation runs on it.
rm -rf "$lib-stage1" && cp -r "$lib" "$lib-stage1"
"$bin" skill eval "$specs/walk.ron" --library "$lib" --trials "$trials"
for s in turn_left turn_right; do
  "$bin" skill finetune "$specs/$s.ron" --from walk --library "$lib" --iterations "${TURN_FINETUNE_ITERS:-400}" "${extra[@]}"
  "$bin" skill eval "$specs/$s.ron" --library "$lib" --trials "$trials" --from walk
done
if [ "${WALK_FINETUNE_ITERS:-800}" != 0 ]; then
  "$bin" skill finetune "$specs/walk.ron" --from turn_left,turn_right --library "$lib" --fraction 0.7 --iterations "${WALK_FINETUNE_ITERS:-800}" "${extra[@]}"
  "$bin" skill eval "$specs/walk.ron" --library "$lib" --trials "$trials" --from turn_left,turn_right --no-pool
fi
"$bin" skill finetune "$specs/sit.ron" --from turn_left,turn_right --library "$lib" --fraction 0.7 --iterations "${SIT_FINETUNE_ITERS:-600}" "${extra[@]}"
if [ "${SIT_FINETUNE2_ITERS:-1000}" != 0 ]; then
  "$bin" skill finetune "$specs/sit.ron" --from turn_left,turn_right --library "$lib" --fraction 0.6 --iterations "${SIT_FINETUNE2_ITERS:-1000}" "${extra[@]}"
fi
"$bin" skill eval "$specs/sit.ron" --library "$lib" --trials "$trials" --from turn_left,turn_right
