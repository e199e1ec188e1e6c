#!/usr/bin/env bash
# Usage: scripts/same-figures.sh BIN_BEFORE BIN_AFTER OUT
#
# Runs the same small evaluations with two builds of `repertoire` (before and after a change that
# must not change behaviour) and compares every file they write, byte for byte: sitting with each
# controller (learned, lookahead, oracle-sit, planner, a gated one over a freshly learned
# readiness), the warehouse and the toss, `run` on sitting (alone and with lookahead) and the
# warehouse, `scene check` of the three scenarios and `report` over two evaluations. Worst-trial
# recordings are compared too; replay pages (which embed their path) and timings are not.
# The controllers are chosen with the older flags (--lookahead K, --planner...), which builds
# from before and after `--controller` both take. Prints one line per check and exits non-zero when any differs. Run from the repository root.
set -euo pipefail
[ $# -eq 3 ] || { sed -n 2,3p "$0" >&2; exit 2; }
before=$1 after=$2 out=$3
export LD_LIBRARY_PATH=$PWD/third_party/mujoco/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}

figures() {
  local bin=$1 dir=$2
  mkdir -p "$dir"
  r() { local name=$1; shift; "$bin" "$@" >"$dir/$name.txt" 2>"$dir/$name.err" || { echo "FAILED $bin $*" >&2; tail -3 "$dir/$name.err" >&2; return 1; }; }
  r sit       meta eval --trials 100 --out "$dir/sit" --worst 1
  r look      meta eval --trials 6 --lookahead 4 --out "$dir/look" --worst 1
  r oracle    meta eval --trials 6 --oracle-sit --out "$dir/oracle" --worst 1
  r planner   meta eval --planner --trials 4 --out "$dir/planner" --worst 1
  r ready     meta readiness --trials 4 --epochs 5 --out "$dir/ready"
  r gated     meta eval --trials 20 --readiness "$dir/ready" --out "$dir/gated" --worst 1
  r warehouse meta eval scenarios/warehouse.ron --trials 20 --grid 2 --grid-trials 2 --out "$dir/warehouse" --worst 1
  r toss      meta eval scenarios/toss.ron --grid 2 --grid-trials 2 --out "$dir/toss" --worst 1
  r run       run --trials 5 --out "$dir/run"
  r runlook   run --trials 2 --lookahead 3 --out "$dir/runlook"
  r runware   run scenarios/warehouse.ron --trials 3 --out "$dir/runware"
  r scenesit  scene check
  r sceneware scene check scenarios/warehouse.ron
  r scenetoss scene check scenarios/toss.ron
  cp -r "$dir/sit" "$dir/sit-report" && r report report "$dir/sit-report"
  cp -r "$dir/warehouse" "$dir/ware-report" && r reportw report "$dir/ware-report"
}

figures "$before" "$out/before"
figures "$after" "$out/after"

status=0
for d in sit look oracle planner gated warehouse toss run runlook runware sit-report ware-report; do
  differ=$(cd "$out/before/$d" && find . -type f ! -name '*.html' ! -name index.md | sort | while read -r f; do
    cmp -s "$f" "../../after/$d/$f" || echo "$f"; done)
  if [ -z "$differ" ]; then echo "same     $d"; else echo "DIFFERS  $d: $differ"; status=1; fi
done
# The readiness: its weights, and its manifest without timings and the command line.
strip() { grep -v -e '_s:' -e 'command:' "$1"; }
if cmp -s "$out/before/ready/readiness.safetensors" "$out/after/ready/readiness.safetensors" &&
   diff <(strip "$out/before/ready/readiness.ron") <(strip "$out/after/ready/readiness.ron") >/dev/null; then
  echo "same     ready"
else echo "DIFFERS  ready"; status=1; fi
for t in scenesit sceneware scenetoss; do
  if diff "$out/before/$t.txt" "$out/after/$t.txt" >/dev/null; then echo "same     $t"; else echo "DIFFERS  $t"; status=1; fi
done
exit $status
