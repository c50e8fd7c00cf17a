"""The aggregate's bootstrap: ``scipy.stats.bootstrap`` (hnnbench._results.stats) against rliable.

    python benchmarks/bootstrap_library.py [--rliable-python PY] [--reps 2000 9999]

Synthetic normalised scores shaped like the leaderboard's (6 families x 11 systems x 5
seeds, heavy-tailed, one family with diverged runs at the clip) go through both:

- the interquartile mean of each family over every (system, seed) run, with the 95%
  percentile interval of the stratified bootstrap (seeds resampled within each system):
  ``hnnbench._results.stats.stratified_interval`` (scipy, one sample per system) and rliable's
  ``get_interval_estimates(..., method="percentile")`` with ``metrics.aggregate_iqm``;
- the probability of improvement of the first family over each other one
  (``hnnbench._results.stats.probability_of_improvement`` and rliable's
  ``probability_of_improvement``).

rliable 1.2.0 needs ``pandas<3`` (through ``arch``); hnnbench's environment has pandas 3,
so rliable runs in a Python of its own given by ``--rliable-python`` (a virtual
environment with ``pip install rliable==1.2.0 'pandas<3'``), fed the same scores through
a temporary ``.npz``. Prints each estimate from both and the seconds each took.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

N_FAMILIES, N_SYSTEMS, N_SEEDS = 6, 11, 5

RLIABLE = r"""
import json, sys, time
import numpy as np
from rliable import library, metrics
scores = np.load(sys.argv[1])["scores"]          # (families, seeds, systems)
out = {}
for reps in json.loads(sys.argv[2]):
    t = time.perf_counter()
    point, ci = library.get_interval_estimates(
        {str(i): scores[i] for i in range(len(scores))},
        lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps,
        random_state=np.random.RandomState(0))
    iqm_s = time.perf_counter() - t
    t = time.perf_counter()
    pairs = {f"0,{j}": (scores[0], scores[j]) for j in range(1, len(scores))}
    p_point, p_ci = library.get_interval_estimates(
        pairs, metrics.probability_of_improvement, reps=reps,
        random_state=np.random.RandomState(0))
    poi_s = time.perf_counter() - t
    out[str(reps)] = {
        "iqm": [[float(point[str(i)][0]), float(ci[str(i)][0, 0]), float(ci[str(i)][1, 0])]
                for i in range(len(scores))],
        "poi": [[float(p_point[k]), *map(float, np.ravel(p_ci[k])[:2])] for k in pairs],
        "iqm_s": iqm_s, "poi_s": poi_s}
print(json.dumps(out))
"""


def synthetic_scores(seed: int = 0) -> np.ndarray:
    """``(families, seeds, systems)`` normalised scores: per-family level, per-system
    offset, heavy-tailed seed noise; family 3 diverges on a tenth of its runs."""
    rng = np.random.default_rng(seed)
    level = np.linspace(0.0, 0.5, N_FAMILIES)[:, None, None]
    system = rng.normal(0.0, 0.1, (1, 1, N_SYSTEMS))
    noise = 0.08 * rng.standard_t(3, (N_FAMILIES, N_SEEDS, N_SYSTEMS))
    scores = level + system + noise
    scores[3][rng.random((N_SEEDS, N_SYSTEMS)) < 0.1] = -10.0
    return scores


def ours(scores: np.ndarray, reps: int) -> dict:
    from hnnbench._results import stats

    stats.N_RESAMPLES = reps  # the module's default is 9999; measured at each count
    stats.stratified_interval([scores[0][:, 0]])  # imports scipy.stats outside the timing
    t = time.perf_counter()
    iqm = [
        list(stats.stratified_interval([scores[i][:, m] for m in range(N_SYSTEMS)]))
        for i in range(len(scores))
    ]
    iqm_s = time.perf_counter() - t
    t = time.perf_counter()
    poi = [
        list(
            stats.probability_of_improvement(
                [scores[0][:, m] for m in range(N_SYSTEMS)],
                [scores[j][:, m] for m in range(N_SYSTEMS)],
            )
        )
        for j in range(1, len(scores))
    ]
    return {"iqm": iqm, "poi": poi, "iqm_s": iqm_s, "poi_s": time.perf_counter() - t}


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--rliable-python", default=None, help="a Python with rliable 1.2.0 and pandas<3 installed"
    )
    parser.add_argument("--reps", type=int, nargs="+", default=[2000, 9999])
    args = parser.parse_args()
    scores = synthetic_scores()
    theirs = {}
    if args.rliable_python:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "scores.npz"
            np.savez(path, scores=scores)
            proc = subprocess.run(
                [args.rliable_python, "-c", RLIABLE, str(path), json.dumps(args.reps)],
                capture_output=True,
                text=True,
                check=True,
            )
            theirs = json.loads(proc.stdout.strip().splitlines()[-1])
    for reps in args.reps:
        mine = ours(scores, reps)
        other = theirs.get(str(reps))
        print(f"\n{reps} resamples: IQM [95% interval] per family; then P(family 0 > j)")
        print(f"{'':10} {'scipy (hnnbench._results.stats)':>34} {'rliable 1.2.0':>34}")
        for kind in ("iqm", "poi"):
            for i, row in enumerate(mine[kind]):
                name = f"fam {i}" if kind == "iqm" else f"P(0>{i + 1})"
                theirs_text = "{:.3f} [{:.3f}, {:.3f}]".format(*other[kind][i]) if other else "—"
                print(f"{name:10} {'{:.3f} [{:.3f}, {:.3f}]'.format(*row):>34} {theirs_text:>34}")
        times = f"IQM {mine['iqm_s']:.2f}, P {mine['poi_s']:.2f}"
        times_rl = f"IQM {other['iqm_s']:.2f}, P {other['poi_s']:.2f}" if other else "—"
        print(f"{'seconds':10} {times:>34} {times_rl:>34}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
