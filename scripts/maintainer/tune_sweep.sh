#!/usr/bin/env bash
# The tuned track (issue 50, docs/TUNING.md "Running the tuned track"), staged and
# resumable: one `hnnbench tune` per system (its own Optuna database, so systems run side
# by side), the JAX twin of each of the six families, TRIALS trials of the protocol's
# steps on SEEDS_PER_TRIAL seeds each (trial 0: the protocol's settings), the selection
# trained on the seed plan 0..SEEDS-1. Re-running the same command resumes every study
# and skips every finished final run.
#
#   scripts/maintainer/tune_sweep.sh STAGE|SYSTEM[,SYSTEM...] [ROOT]   ROOT default: results/runs/tuned_paper
#     stage 1: the five systems tuned before (spring, damped_spring, pendulum,
#              damped_pendulum, real_pendulum)
#     stage 2: two_body, double_pendulum
#     stage 3: the rest, cheapest first, three_body last (spring_chain, pixel_pendulum,
#              real_double_pendulum, three_body; on pixel_pendulum only the MLP and the
#              HNN run: the other families are recorded skipped, untuned)
#   JOBS=2 TRIALS=16 SEEDS=10 SEEDS_PER_TRIAL=2 scripts/maintainer/tune_sweep.sh 1
#
# Each system's log: ROOT/<system>.log. Report beside the protocol track with
#   .venv/bin/hnnbench report results/records ROOT/final --out OUT
set -euo pipefail
cd "$(dirname "$0")/../.."
what=${1:?usage: scripts/maintainer/tune_sweep.sh STAGE|SYSTEM[,SYSTEM...] [ROOT]}
root=${2:-results/runs/tuned_paper}
jobs=${JOBS:-2}
trials=${TRIALS:-16}
seeds=$(seq -s, 0 $(( ${SEEDS:-10} - 1 )))
per_trial=${SEEDS_PER_TRIAL:-2}
export HNNBENCH_DATA_DIR="${HNNBENCH_DATA_DIR:-$(cd .. && pwd)/shared/data/schmidt-lipson-2009}"
export HNNBENCH_PROGRESS=log
models=mlp_jax,hnn_jax,dhnn_jax,lnn_jax,so_mlp_jax,srnn_jax
case "$what" in
  1) systems="spring damped_spring pendulum damped_pendulum real_pendulum" ;;
  2) systems="two_body double_pendulum" ;;
  3) systems="spring_chain pixel_pendulum real_double_pendulum three_body" ;;
  *) systems=${what//,/ } ;;
esac
mkdir -p "$root"
tune_one() {
  local system=$1
  echo "tune_sweep: $system: $models, $trials trials x $per_trial seeds, final seeds $seeds" >&2
  nice -n 15 .venv/bin/hnnbench tune "system=$system" "model=$models" "trials=$trials" \
    "seeds=$seeds" "seeds_per_trial=$per_trial" profile=paper "out=$root" \
    >> "$root/$system.log" 2>&1
}
export -f tune_one
export models trials seeds per_trial root
printf '%s\n' $systems | xargs -P "$jobs" -I{} bash -c 'tune_one {}'
