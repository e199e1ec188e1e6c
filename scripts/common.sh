# Sourced by the training scripts: moves to the repository root, runs the set-up step, builds the
# release binary into $bin, sets $specs (the skill specs), $trials (TRIALS, 1000) and $extra
# (EXTRA, more arguments for every train/finetune), and defines `eval_skill ARGS…`, which runs
# `skill eval ARGS…` over $lib with $trials trials and appends its table, under the command, to
# the file $evals.
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
cargo build --release --quiet
bin="$root/target/release/repertoire"
specs=skills/skill/specs
trials="${TRIALS:-1000}"
extra=(${EXTRA:-})

eval_skill() {
  local out
  out="$("$bin" skill eval "$@" --library "$lib" --trials "$trials")"
  printf '%s\n' "$out"
  printf '\n## `repertoire skill eval %s`\n\n%s\n' "$*" "$out" >> "$evals"
}
