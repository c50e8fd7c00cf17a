"""Does a system's step budget decide its verdicts? The same seeds of every family at two
or more step budgets, side by side (issue 46, "Training long enough").

Reads the records under the directories given (a pilot's sweep, ``results/records``),
keeps the protocol-track ``ok`` records of the systems and seeds asked for, and groups
them by the step budget they trained for (the selection's final evaluated step). Per
system, budget and family: the seeds, how many converged (``selection.converged``: the
criterion fell by at most 2 paired standard errors over the last 20 % of steps), and the
means over those seeds of the criterion at the final checkpoint and of the headline
metrics. Then, per system and metric, the order of the families by their means at each
budget, and whether doubling the budget changed it. Two seeds give an order, not a
verdict: a changed order says the budget matters, an unchanged one does not prove it
does not.

    python scripts/analysis/budget_pilot.py /work/repub/runs/pilot results/records \\
        --systems two_body,double_pendulum --seeds 0,1
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import pandas as pd

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

#: The metrics compared (lower is better for each).
METRICS = ("criterion", "test_loss", "energy_mse", "rollout_mse")


def rows(directories: list[Path], systems: set[str], seeds: set[int]) -> pd.DataFrame:
    """One row per (system, family, steps, seed) of the ok protocol records given."""
    from hnnbench import _record as records
    from hnnbench._record.tracks import track_of

    out: dict[tuple[str, str, int, int], dict[str, object]] = {}
    for directory in directories:
        recs, _ = records.load(directory)
        for rec in recs:
            sel = rec.get("selection")
            if (
                rec.get("system") not in systems
                or rec.get("seed") not in seeds
                or rec.get("status") != "ok"
                or rec.get("reference")
                or track_of(rec) != "protocol"
                or not isinstance(sel, dict)
                or not sel.get("final_step")
            ):
                continue
            metrics = rec.get("metrics", {})
            key = (rec["system"], str(rec["family"]), int(sel["final_step"]), int(rec["seed"]))
            out[key] = {
                "system": key[0],
                "family": key[1],
                "steps": key[2],
                "seed": key[3],
                "converged": sel.get("converged") is True,
                "criterion": float(sel.get("final_value", math.nan)),
                **{m: float(metrics.get(m, {}).get("mean", math.nan)) for m in METRICS[1:]},
            }
    return pd.DataFrame(list(out.values()))


def summary(frame: pd.DataFrame) -> pd.DataFrame:
    """Per (system, steps, family): seeds, converged seeds, means over the seeds."""
    grouped = frame.groupby(["system", "steps", "family"], sort=True)
    table = grouped[list(METRICS)].mean()
    table.insert(0, "converged", grouped["converged"].sum().astype(int))
    table.insert(0, "seeds", grouped["seed"].count())
    return table.reset_index()


def orders(table: pd.DataFrame) -> list[str]:
    """Per system and metric: the families by mean at each budget, and whether it changed."""
    lines = []
    for system, sub in table.groupby("system", sort=True):
        budgets = sorted(sub["steps"].unique())
        if len(budgets) < 2:
            lines.append(f"- `{system}`: one budget only ({budgets[0]} steps); nothing to compare.")
            continue
        for metric in METRICS:
            ranked = {
                b: " < ".join(sub[sub["steps"] == b].sort_values(metric)["family"]) for b in budgets
            }
            same = len(set(ranked.values())) == 1
            shown = "; ".join(f"{b}: {r}" for b, r in ranked.items())
            lines.append(
                f"- `{system}`, {metric}: {'same order' if same else 'order changes'} ({shown})"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dirs", nargs="+", type=Path, help="directories of records")
    parser.add_argument("--systems", default="two_body,double_pendulum")
    parser.add_argument("--seeds", default="0,1")
    args = parser.parse_args(argv)
    missing = [str(d) for d in args.dirs if not d.is_dir()]
    if missing:
        print(f"budget_pilot: not a directory: {', '.join(missing)}", file=sys.stderr)
        return 2
    try:
        seeds = {int(s) for s in args.seeds.split(",") if s}
    except ValueError:
        print(f"budget_pilot: --seeds {args.seeds!r}: expected integers, e.g. 0,1", file=sys.stderr)
        return 2
    frame = rows(args.dirs, set(args.systems.split(",")), seeds)
    if frame.empty:
        print("budget_pilot: no ok protocol record of those systems and seeds", file=sys.stderr)
        return 1
    table = summary(frame)
    shown = table.copy()
    for metric in METRICS:
        shown[metric] = [f"{v:.3g}" for v in shown[metric]]
    print(shown.to_markdown(index=False))
    print()
    print("\n".join(orders(table)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
