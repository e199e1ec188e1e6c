#!/usr/bin/env bash
# Trains the default skill library (walk, turn_left, turn_right, sit) from scratch, the way the
# shipped skills/library was made, and evaluates it (the sitting paper's two stages):
#   1. each skill from its spec with reference-state initialisation;
#   2. transition fine-tuning: the turns from walk's end poses, sit from the turns' end poses;
#   3. `skill eval` over TRIALS trials from the clip start and from predecessors' end poses
#      (which also writes each skill's end-pose pool, used by the next stage).
# Usage: bash scripts/train-library.sh [LIBRARY] — env: TRIALS (1000), FINETUNE_ITERS (the spec's),
# EXTRA (more arguments for every train/finetune, e.g. "--iterations 50" for a smoke run).
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
"$bin" skill eval "$specs/walk.ron" --library "$lib" --trials "$trials"
for s in turn_left turn_right; do
  "$bin" skill finetune "$specs/$s.ron" --from walk --library "$lib" ${FINETUNE_ITERS:+--iterations "$FINETUNE_ITERS"} "${extra[@]}"
  "$bin" skill eval "$specs/$s.ron" --library "$lib" --trials "$trials" --from walk
done
"$bin" skill finetune "$specs/sit.ron" --from turn_left,turn_right --library "$lib" ${FINETUNE_ITERS:+--iterations "$FINETUNE_ITERS"} "${extra[@]}"
"$bin" skill eval "$specs/sit.ron" --library "$lib" --trials "$trials" --from turn_left,turn_right
