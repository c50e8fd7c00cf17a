"""Does a system's step budget decide its verdicts? Every family's seeds at two step
budgets side by side, against how much a change of seeds alone moves the same order
(issue 46, "Training long enough").

Reads the protocol-track records of one backend's twins under the directories given (a
pilot's sweep, ``results/records``) and groups them by the step budget they trained for
(the record's ``steps``). A diverged seed counts: its metrics are infinite where the
rollout failed and it counts as not converged; a failed or skipped job is left out and
said. Per system, budget and family: the seeds, diverged and converged seeds
(``selection.converged``: the criterion fell by at most 2 paired standard errors over
the last 20 % of steps), and geometric means over the compared seeds (the metrics span
orders of magnitude) of the criterion at the final checkpoint and of the headline
metrics.

Then, per system and metric, how alike the families' orders are (Kendall's tau, 1: the
same order): between the two budgets on the compared seeds (``--seeds``), and, as the
noise it must be read against, between disjoint pairs of seeds at one budget (seeds 0-1
against 2-3, ...; every budget with at least four seeds). Doubling "moves the order more
than a change of seeds" where the tau between budgets is below the lowest tau between
seed pairs. Two seeds give an order, not a verdict.

    python scripts/analysis/budget_pilot.py /work/repub/runs/pilot results/records \\
        --systems two_body,double_pendulum --seeds 0,1
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import kendalltau

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

#: The metrics compared; lower is better for each.
METRICS = ("criterion", "test_loss", "energy_mse", "rollout_mse")


def _value(metrics: dict, name: str) -> float:
    try:
        return float(metrics.get(name, {}).get("mean", math.nan))
    except (TypeError, ValueError):
        return math.nan


def rows(
    directories: list[Path], systems: set[str], backend: str
) -> tuple[pd.DataFrame, list[str]]:
    """One row per (system, model, steps, seed) of the protocol records given (ok or
    diverged), and a line per job left out (failed, skipped, timed out)."""
    from hnnbench import _record as records
    from hnnbench._record.tracks import track_of

    out: dict[tuple[str, str, int, int], dict[str, object]] = {}
    left_out: list[str] = []
    for directory in directories:
        recs, _ = records.load(directory)
        for rec in recs:
            if (
                rec.get("system") not in systems
                or rec.get("backend") != backend
                or rec.get("reference")
                or track_of(rec) != "protocol"
            ):
                continue
            key = (str(rec["system"]), str(rec["model"]), int(rec["steps"]), int(rec["seed"]))
            if rec.get("status") not in ("ok", "diverged"):
                left_out.append(
                    f"{key[0]}/{key[1]} seed {key[3]} at {key[2]} steps: {rec.get('status')}"
                )
                continue
            sel = rec.get("selection") if isinstance(rec.get("selection"), dict) else {}
            metrics = rec.get("metrics", {})
            diverged = rec["status"] == "diverged"
            out[key] = {
                "system": key[0],
                "family": str(rec.get("family") or key[1]),
                "steps": key[2],
                "seed": key[3],
                "diverged": diverged,
                "converged": (sel.get("converged") is True) and not diverged,
                "criterion": float(sel.get("final_value", math.nan)),
                **{m: _value(metrics, m) for m in METRICS[1:]},
            }
    return pd.DataFrame(list(out.values())), left_out


def _geomean(values: pd.Series) -> float:
    v = values.to_numpy(dtype=float)
    if np.isnan(v).any():
        return math.nan
    if np.isinf(v).any():
        return math.inf
    return float(np.exp(np.mean(np.log(np.maximum(v, 1e-300)))))


def summary(frame: pd.DataFrame) -> pd.DataFrame:
    """Per (system, steps, family): seeds, diverged and converged seeds, geometric means."""
    grouped = frame.groupby(["system", "steps", "family"], sort=True)
    table = grouped[list(METRICS)].agg(_geomean)
    table.insert(0, "converged", grouped["converged"].sum().astype(int))
    table.insert(0, "diverged", grouped["diverged"].sum().astype(int))
    table.insert(0, "seeds", grouped["seed"].count())
    return table.reset_index()


def _tau(a: pd.Series, b: pd.Series) -> float:
    """Kendall's tau (tau-b: ties allowed) of two families -> value series over their
    shared families; an infinite value ranks last."""
    shared = a.index.intersection(b.index)
    if len(shared) < 3:
        return math.nan
    return float(kendalltau(a[shared].to_numpy(), b[shared].to_numpy()).statistic)


def _means(frame: pd.DataFrame, seeds: tuple[int, ...], metric: str) -> pd.Series:
    """The families' geometric means of ``metric`` over exactly ``seeds`` (a family
    without every one of them is left out)."""
    sub = frame[frame["seed"].isin(seeds)]
    counts = sub.groupby("family")["seed"].nunique()
    full = counts[counts == len(seeds)].index
    return sub[sub["family"].isin(full)].groupby("family")[metric].agg(_geomean)


def orders(frame: pd.DataFrame, seeds: tuple[int, ...]) -> list[str]:
    """Per system and metric: tau between the budgets on ``seeds``, and between disjoint
    seed pairs at one budget, with the reading."""
    lines = []
    for system, sub in frame.groupby("system", sort=True):
        budgets = sorted(sub["steps"].unique())
        if len(budgets) < 2:
            lines.append(f"- `{system}`: one budget only ({budgets[0]} steps); nothing to compare.")
            continue
        low, high = budgets[0], budgets[-1]
        for metric in METRICS:
            at = {b: _means(sub[sub["steps"] == b], seeds, metric) for b in (low, high)}
            between = _tau(at[low], at[high])
            noise: list[float] = []
            for b in (low, high):
                one = sub[sub["steps"] == b]
                have = sorted(one["seed"].unique())
                pairs = [tuple(have[i : i + 2]) for i in range(0, len(have) - 1, 2)]
                for p, q in itertools.combinations(pairs, 2):
                    noise.append(_tau(_means(one, p, metric), _means(one, q, metric)))
            noise = [t for t in noise if math.isfinite(t)]
            order = {b: " < ".join(at[b].sort_values().index) for b in (low, high)}
            shown = f"{low}: {order[low]}; {high}: {order[high]}"
            if not noise or not math.isfinite(between):
                reading = "no seed pairs to read it against"
            elif between < min(noise):
                reading = "doubling moves the order more than a change of seeds"
            else:
                reading = "doubling moves the order no more than a change of seeds"
            spread = "no seed pairs"
            if noise:
                spread = f"seed pairs {min(noise):.2f} to {max(noise):.2f}"
                spread += f" (median {np.median(noise):.2f}, {len(noise)})"
            lines.append(
                f"- `{system}`, {metric}: tau between budgets {between:.2f}, {spread}: "
                f"{reading} ({shown})"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dirs", nargs="+", type=Path, help="directories of records")
    parser.add_argument("--systems", default="two_body,double_pendulum")
    parser.add_argument("--seeds", default="0,1", help="the seeds compared between budgets")
    parser.add_argument("--backend", default="jax", help="whose twins (jax or torch)")
    args = parser.parse_args(argv)
    missing = [str(d) for d in args.dirs if not d.is_dir()]
    if missing:
        print(f"budget_pilot: not a directory: {', '.join(missing)}", file=sys.stderr)
        return 2
    try:
        seeds = tuple(sorted({int(s) for s in args.seeds.split(",") if s}))
    except ValueError:
        print(f"budget_pilot: --seeds {args.seeds!r}: expected integers, e.g. 0,1", file=sys.stderr)
        return 2
    frame, left_out = rows(args.dirs, set(args.systems.split(",")), args.backend)
    for line in left_out:
        print(f"budget_pilot: left out {line}", file=sys.stderr)
    if frame.empty:
        print("budget_pilot: no ok or diverged protocol record of those systems", file=sys.stderr)
        return 1
    table = summary(frame[frame["seed"].isin(seeds)])
    shown = table.copy()
    for metric in METRICS:
        shown[metric] = [f"{v:.3g}" for v in shown[metric]]
    print(f"Seeds {', '.join(map(str, seeds))}; geometric means over them.\n")
    print(shown.to_markdown(index=False))
    print()
    print("\n".join(orders(frame, seeds)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
