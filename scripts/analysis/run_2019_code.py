"""Run the authors' own 2019 n-body experiments side by side with hnnbench's rows.

    python scripts/analysis/run_2019_code.py --repo PATH [--experiment 2body|3body]
        [--seeds 0 1 2] [--python PYTHON] [--workdir DIR] [--threads 1]

``PATH`` is a checkout of https://github.com/greydanus/hamiltonian-nn (untouched; this
script only calls its ``experiment-<name>/train.py``). ``PYTHON`` must have torch, numpy,
scipy and imageio (the original imports the last one); the default is this interpreter.

For each seed, the HNN and then the baseline are trained by the original script with
``--seed <s> --save_dir <workdir>/seed<s>``. As in the original, each seed draws and
caches its own dataset (``np.random.seed`` precedes the data), shared by its two runs.
The script reads the original's "Final train loss / Final test loss" lines (the whole
split, in float32), writes them to ``<workdir>/results.csv`` and prints, per model and
split, the 3-seed mean, the published value (the ``greydanus2019`` claim set) and
hnnbench's committed leaderboard mean (results/leaderboard.csv, the torch twins), with
ratios. Finished runs are kept: a re-run parses the existing logs instead of retraining.

Each run is pinned to ``--threads`` CPU threads (OMP/MKL/OpenBLAS; default 1): the
original's float32 training is sensitive to the summation order, and its seed-0 two-body
HNN ends at a train loss of 6.71e-6 on one thread and 6.20e-6 on two.

This answers one question: does a gap between hnnbench and the published numbers come
from hnnbench's protocol, or does the original code show it too on this machine?
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import subprocess
import sys
import time
from pathlib import Path

from hnnbench._registry.groups import claim_sets

ROOT = Path(__file__).resolve().parents[2]
SYSTEM = {"2body": "two_body", "3body": "three_body"}
FINAL = re.compile(r"Final (train|test) loss ([0-9.eE+-]+) \+/- ([0-9.eE+-]+)")
HNNBENCH_MODEL = {"hnn": "hnn_torch", "baseline": "mlp_torch"}


def parse_log(log: Path) -> dict[str, float] | None:
    """``{"train_loss": …, "test_loss": …}`` from a finished original run's log, else None."""
    if not log.is_file():
        return None
    found = {f"{m[1]}_loss": float(m[2]) for m in FINAL.finditer(log.read_text())}
    return found if len(found) == 2 else None


def run_one(ns: argparse.Namespace, seed: int, kind: str) -> dict[str, float]:
    """Train one original model (or reuse its log) and return its final losses."""
    out = ns.workdir / f"seed{seed}"
    out.mkdir(parents=True, exist_ok=True)
    log = out / f"{kind}.log"
    done = parse_log(log)
    if done is not None:
        print(f"seed {seed} {kind}: reusing {log}", flush=True)
        return done
    script = ns.repo / f"experiment-{ns.experiment}" / "train.py"
    cmd = [ns.python, str(script), "--seed", str(seed), "--save_dir", str(out)]
    if kind == "baseline":
        cmd.append("--baseline")
    print(f"seed {seed} {kind}: {' '.join(cmd)}", flush=True)
    start = time.perf_counter()
    threads = str(ns.threads)
    env = {**os.environ, "OMP_NUM_THREADS": threads, "MKL_NUM_THREADS": threads}
    env["OPENBLAS_NUM_THREADS"] = threads
    with log.open("w") as fh:
        rc = subprocess.run(
            cmd, stdout=fh, stderr=subprocess.STDOUT, env=env, check=False
        ).returncode
    result = parse_log(log)
    if rc != 0 or result is None:
        sys.exit(f"error: the original script failed (exit {rc}); see {log}")
    print(
        f"  {time.perf_counter() - start:.0f} s: train {result['train_loss']:.3e}, "
        f"test {result['test_loss']:.3e}",
        flush=True,
    )
    return result


def reference_values(system: str) -> tuple[dict, dict]:
    """Published values (the ``greydanus2019`` claim set) and hnnbench's leaderboard
    means, keyed by (kind, metric)."""
    paper = {
        (p.role, p.metric): p.value
        for cs in claim_sets()
        if cs.name == "greydanus2019"
        for p in cs.published
        if p.system == system
    }
    ours: dict[tuple[str, str], float] = {}
    board = ROOT / "results/leaderboard.csv"
    if board.is_file():
        with board.open() as fh:
            for row in csv.DictReader(fh):
                if row["profile"] != "paper" or row["system"] != system:
                    continue
                for kind, model in HNNBENCH_MODEL.items():
                    if row["model"] == model:
                        for metric in ("train_loss", "test_loss"):
                            if row[f"{metric}_mean"]:
                                ours[(kind, metric)] = float(row[f"{metric}_mean"])
    return paper, ours


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--repo", type=Path, required=True, help="a checkout of greydanus/hamiltonian-nn"
    )
    parser.add_argument("--experiment", choices=sorted(SYSTEM), default="2body")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--python", default=sys.executable)
    parser.add_argument("--threads", type=int, default=1, help="CPU threads per run")
    parser.add_argument(
        "--workdir", type=Path, default=None, help="default: results/runs/original-<experiment>"
    )
    ns = parser.parse_args(argv)
    script = ns.repo / f"experiment-{ns.experiment}" / "train.py"
    if not script.is_file():
        parser.error(
            f"{script} does not exist: --repo must be a checkout of "
            "greydanus/hamiltonian-nn (git clone https://github.com/greydanus/hamiltonian-nn)"
        )
    ns.workdir = (ns.workdir or ROOT / f"results/runs/original-{ns.experiment}").resolve()

    rows = []
    for seed in ns.seeds:
        for kind in ("hnn", "baseline"):
            rows.append({"seed": seed, "model": kind, **run_one(ns, seed, kind)})
    with (ns.workdir / "results.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=["seed", "model", "train_loss", "test_loss"])
        writer.writeheader()
        writer.writerows(rows)

    system = SYSTEM[ns.experiment]
    paper, ours = reference_values(system)
    print(
        f"\n{system}: the original code, seeds {ns.seeds} (mean), against the published "
        "value and hnnbench's committed 3-seed mean"
    )
    print(
        f"{'model':9} {'metric':11} {'original':>10} {'published':>10} {'orig/pub':>9} "
        f"{'hnnbench':>10} {'hnnb/orig':>9}"
    )
    for kind in ("baseline", "hnn"):
        for metric in ("train_loss", "test_loss"):
            vals = [r[metric] for r in rows if r["model"] == kind]
            mean = sum(vals) / len(vals)
            pub = paper.get((kind, metric))
            hb = ours.get((kind, metric))
            print(
                f"{kind:9} {metric:11} {mean:10.3e} "
                f"{pub if pub is not None else float('nan'):10.3e} "
                f"{mean / pub if pub else float('nan'):9.2f} "
                f"{hb if hb is not None else float('nan'):10.3e} "
                f"{hb / mean if hb is not None else float('nan'):9.2f}"
            )
    print(f"\nper-seed values: {ns.workdir / 'results.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
