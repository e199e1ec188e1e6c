#!/usr/bin/env bash
# The chair-aware walk and a sitting controller over it (stop 40; an experiment, not the default):
#   1. walk_around (`specs/walk_around.ron`) grown from the library's walk_to: the chair's pose
#      enters its observation with zero weights and it trains in `arena_chair.ron` with the chair
#      put in the way of half its targets, a touch ending the episode (WALK_AROUND_ITERS, 2000,
#      its spread raised to log std -2.2 first);
#   2. evaluated with the chair in the way, writing its end-pose pool (the sitting episodes
#      start from the first start skill's pool), and with the chair never put in the way;
#   3. the library's sitting controller warm-started over `scenes/sit_around.ron` (the default
#      with walk_around in walk_to's place: `--replace walk_to=walk_around`), META_ITERS (800)
#      iterations, every zone open, into LIBRARY/meta-around, then evaluated there.
# Usage: bash scripts/train-walk-around.sh [LIBRARY] — env: TRIALS (1000), EXTRA (more arguments
# for the skill's training). LIBRARY (default runs/library-around) is written into; when it does
# not exist it starts as a copy of skills/library, so the committed library is left as it is.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
lib="${1:-runs/library-around}"
if [[ ! -e "$lib" ]]; then
  mkdir -p "$(dirname "$lib")"
  cp -r skills/library "$lib.tmp.$$"
  mv "$lib.tmp.$$" "$lib"
  echo "$lib: a copy of skills/library"
fi
evals="$lib/evals.md"

"$bin" skill train "$specs/walk_around.ron" --warm-start-from walk_to --explore-log-std -2.2 \
  --iterations "${WALK_AROUND_ITERS:-2000}" --library "$lib" "${extra[@]}"
eval_skill "$specs/walk_around.ron"
clear="$(mktemp -d)"
trap 'rm -rf "$clear"' EXIT
cp "$specs/arena_chair.ron" "$clear/"
sed 's/chance: [0-9.]*/chance: 0.0/' "$specs/walk_around.ron" > "$clear/walk_around.ron"
eval_skill "$clear/walk_around.ron" --no-pool
"$bin" meta train scenes/sit_around.ron --library "$lib" --warm-start "$lib/meta" \
  --replace walk_to=walk_around --no-curriculum --learning-rate 1.5e-4 \
  --iterations "${META_ITERS:-800}" --out "$lib/meta-around"
"$bin" meta eval scenes/sit_around.ron --library "$lib" --meta "$lib/meta-around" --trials "$trials"
echo "walk_around and its controller added to $lib (evaluations appended to $evals)"
