#!/usr/bin/env bash
# The committed paper-profile leaderboard's runs of one or more systems, resumable, by
# the protocol's seed plan (docs/STATISTICS.md, "The seed plan"):
#   - the JAX twin of every family and the references (every installed jax or numpy
#     model) on seeds 0..JAX_SEEDS-1 (default 10): the family rows rest on these paired
#     seeds;
#   - the torch twin of every family on seeds 0..TORCH_SEEDS-1 (default 3): the
#     twin-parity check.
# Each system gets two sweep directories, ROOT/<system>/jax and ROOT/<system>/torch;
# re-running the same command skips every finished job (docs/SCALING.md). Publish with
#   .venv/bin/python scripts/maintainer/publish_results.py ROOT/SYSTEM/jax ROOT/SYSTEM/torch results/records
# (only sweeps not yet published next to results/records: a job given twice is refused)
#
#   scripts/maintainer/paper_sweep.sh SYSTEM[,SYSTEM...] [ROOT]      ROOT default: results/runs/paper
#   JOBS=2 JAX_SEEDS=10 TORCH_SEEDS=3 scripts/maintainer/paper_sweep.sh spring
set -euo pipefail
cd "$(dirname "$0")/../.."
systems=${1:?usage: scripts/maintainer/paper_sweep.sh SYSTEM[,SYSTEM...] [ROOT]}
root=${2:-results/runs/paper}
jobs=${JOBS:-$(env -u OMP_NUM_THREADS nproc 2>/dev/null || echo 1)}
export HNNBENCH_DATA_DIR="${HNNBENCH_DATA_DIR:-$(cd .. && pwd)/shared/data/schmidt-lipson-2009}"
hnnbench=.venv/bin/hnnbench
# The installed models by backend (every registered model that can run here).
models() {
  .venv/bin/python - "$1" <<'EOF'
import json, subprocess, sys
listing = json.loads(subprocess.run([".venv/bin/hnnbench", "list", "--json"], check=True,
                                    capture_output=True, text=True).stdout)
want = sys.argv[1].split("+")
print(",".join(m["name"] for m in listing["model"]
               if m["status"] == "ok" and m["backend"] in want))
EOF
}
seeds() { seq -s, 0 $(( $1 - 1 )); }
jax_models=$(models "jax+numpy")
torch_models=$(models torch)
for system in ${systems//,/ }; do
  echo "paper_sweep: $system: JAX twins and the oracle, seeds $(seeds "${JAX_SEEDS:-10}")" >&2
  "$hnnbench" -m "system=$system" "model=$jax_models" "seed=$(seeds "${JAX_SEEDS:-10}")" \
    hydra/launcher=joblib "hydra.launcher.n_jobs=$jobs" "hydra.sweep.dir=$root/$system/jax"
  echo "paper_sweep: $system: torch twins, seeds $(seeds "${TORCH_SEEDS:-3}")" >&2
  "$hnnbench" -m "system=$system" "model=$torch_models" "seed=$(seeds "${TORCH_SEEDS:-3}")" \
    hydra/launcher=joblib "hydra.launcher.n_jobs=$jobs" "hydra.sweep.dir=$root/$system/torch"
done
