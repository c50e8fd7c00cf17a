"""Does a new run of one seed land inside a committed leaderboard's mean ± k std?

    python scripts/analysis/seed_in_band.py SWEEP [SWEEP ...] \
        --leaderboard results/leaderboard.csv [--k 3] \
        [--metrics train_loss,test_loss,energy_mse,rollout_mse]

For every ``ok`` record of the sweeps whose (profile, system, model) has a row in the
leaderboard, each metric is one cell: inside when |value - mean| <= k * std (a
one-seed row, std empty, needs the value to equal the mean). Prints every cell that
falls outside, then the count ``inside / cells``, and which sweep pairs had no
leaderboard row. Exit status 0 when every cell is inside.

This is issue 21's reproduction criterion ("seed 0 at HEAD within the committed mean ± 3
std for every pair and metric"). With three seeds, ± 3 std is a narrow band for
sensitive pairs (docs/SYSTEMS_PIXEL.md): a cell outside is a prompt to look, not proof
of a change.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import pandas as pd


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sweeps", nargs="+", type=Path)
    parser.add_argument("--leaderboard", type=Path, required=True)
    parser.add_argument("--k", type=float, default=3.0)
    parser.add_argument("--metrics", default="train_loss,test_loss,energy_mse,rollout_mse")
    ns = parser.parse_args(argv)
    if not ns.leaderboard.is_file():
        parser.error(f"{ns.leaderboard} does not exist: give a leaderboard.csv")
    board = pd.read_csv(ns.leaderboard)
    rows = {(r.profile, r.system, r.model): r for r in board.itertuples()}
    metrics = [m for m in ns.metrics.split(",") if m]
    inside = cells = 0
    missing: set[tuple[str, str]] = set()
    for sweep in ns.sweeps:
        for path in sorted(sweep.rglob("result.json")):
            rec = json.loads(path.read_text())
            if rec.get("status") != "ok":
                continue
            row = rows.get((rec.get("profile"), rec["system"], rec["model"]))
            if row is None:
                missing.add((rec["system"], rec["model"]))
                continue
            for metric in metrics:
                value = (rec["metrics"].get(metric) or {}).get("mean")
                mean = getattr(row, f"{metric}_mean", math.nan)
                std = getattr(row, f"{metric}_std", math.nan)
                if value is None or isinstance(value, str) or pd.isna(mean):
                    continue
                std = 0.0 if pd.isna(std) else float(std)
                cells += 1
                if abs(float(value) - float(mean)) <= ns.k * std:
                    inside += 1
                else:
                    print(
                        f"outside: {rec['system']} x {rec['model']} seed {rec['seed']} "
                        f"{metric} = {float(value):.4g}, band {float(mean):.4g} ± "
                        f"{ns.k:g} x {std:.2g}"
                    )
    print(f"{inside} / {cells} cells inside mean ± {ns.k:g} std of {ns.leaderboard}")
    if missing:
        print("no leaderboard row for: " + ", ".join(f"{s} x {m}" for s, m in sorted(missing)))
    return 0 if inside == cells else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
