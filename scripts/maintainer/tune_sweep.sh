#!/usr/bin/env bash
# The tuned track (issue 50, docs/TUNING.md "Running the tuned track"), staged and
# resumable: one `hnnbench tune` per (system, family), the JAX twin of each of the six
# families, each study in its own out= folder ROOT/<system>/<model> (so a finished study
# is published on its own: "Publishing in parts"), TRIALS trials of the protocol's steps
# on SEEDS_PER_TRIAL seeds each (trial 0: the protocol's settings), the selection trained
# on the seed plan 0..SEEDS-1. Re-running the same command resumes every study and skips
# every finished final run.
#
#   scripts/maintainer/tune_sweep.sh STAGE|SYSTEM[,SYSTEM...] [ROOT]   ROOT default: results/runs/tuned_paper
#     stage 1: the five systems tuned before (spring, damped_spring, pendulum,
#              damped_pendulum, real_pendulum)
#     stage 2: two_body, double_pendulum
#     stage 3: the rest, cheapest first, three_body last (spring_chain, pixel_pendulum,
#              real_double_pendulum, three_body; on pixel_pendulum only the MLP and the
#              HNN run: the other families are recorded skipped, untuned)
#   JOBS=2 TRIALS=16 SEEDS=10 SEEDS_PER_TRIAL=2 scripts/maintainer/tune_sweep.sh 1
#   DRY_RUN=1 ... prints each study's command instead of running it
#
# JOBS studies run side by side (one process each), dearest first within a system. Each
# study's log: ROOT/<system>/<model>.log. A measured system's five fold studies run as
# five processes, fold k's in ROOT/<system>_fold<k>/<model> (its log
# ROOT/<system>/<model>.fold<k>.log), so they too use every core (a measured study begun
# in ROOT/<system>/<model> before this layout is resumed only from there: run its
# `hnnbench tune` by hand with that out=). Publish what finished
# (any time; it is staged until its system's every family is in):
#   .venv/bin/python scripts/maintainer/publish_results.py --tuned ROOT/*/*/
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
# dearest first (the published job costs), so the last study to end is a cheap one
models="srnn_jax lnn_jax dhnn_jax hnn_jax mlp_jax so_mlp_jax"
case "$what" in
  1) systems="spring damped_spring pendulum damped_pendulum real_pendulum" ;;
  2) systems="two_body double_pendulum" ;;
  3) systems="spring_chain pixel_pendulum real_double_pendulum three_body" ;;
  *) systems=${what//,/ } ;;
esac
# The measured systems: a seed s tests on fold (4 - s) mod 5 of the series (docs/DATA.md,
# "Folds of a measured series"), and each fold has a study of its own.
measured=" real_pendulum real_double_pendulum "
tune_one() {  # system/model[/fold k/its final seeds]
  local system model fold="" final=$seeds out log
  IFS=/ read -r system model fold final <<< "$1"
  final=${final:-$seeds}
  out=$root/$system/$model log=$root/$system/$model.log
  if [ -n "$fold" ]; then
    out=$root/${system}_fold$fold/$model log=$root/$system/$model.fold$fold.log
  fi
  echo "tune_sweep: $system/$model${fold:+ fold $fold}: $trials trials x $per_trial seeds," \
    "final seeds $final" >&2
  local cmd=(.venv/bin/hnnbench tune "system=$system" "model=$model" "trials=$trials"
    "seeds=$final" "seeds_per_trial=$per_trial" profile=paper "out=$out")
  if [ -n "$dry_run" ]; then echo "${cmd[*]}"; return; fi
  mkdir -p "$root/$system"
  nice -n 15 "${cmd[@]}" >> "$log" 2>&1
}
export -f tune_one
dry_run=${DRY_RUN:-}
export trials seeds per_trial root dry_run
for system in $systems; do
  for model in $models; do
    if [[ $measured == *" $system "* ]]; then
      for s in 0 1 2 3 4; do
        fold_seeds=$(seq -s, "$s" 5 $(( ${SEEDS:-10} - 1 )))
        if [ -n "$fold_seeds" ]; then echo "$system/$model/$(( (4 - s) % 5 ))/$fold_seeds"; fi
      done
    else
      echo "$system/$model"
    fi
  done
done | xargs -P "$jobs" -I{} bash -c 'tune_one {}'
