#!/usr/bin/env bash
# Makes the NPMP latent low level from the committed skill library, the way
# skills/library/latent was made: expert rollouts with action noise (σ 0.1) from random clip
# frames of walk, turn_left, turn_right and sit, the encoder/decoder trained for a bounded time,
# one-shot imitation against the experts, and a go-to-target high level trained over z.
# Usage: bash scripts/train-latent.sh [OUT] — env: STEPS (25000 per skill), MINUTES (20),
# EPISODES (100), GOTO_ITERS (1500), WEIGHTING (bc | clip | rwr).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
out="${1:-skills/library/latent}"
data="runs/latent-data-$(date +%s)"
"$bin" latent collect --steps "${STEPS:-25000}" --out "$data"
"$bin" latent train "$data" --minutes "${MINUTES:-20}" --weighting "${WEIGHTING:-bc}" --out "$out"
"$bin" latent eval "$out" --episodes "${EPISODES:-100}"
"$bin" latent goto "$out" --iterations "${GOTO_ITERS:-1500}"
