"""A new model's rank among the reference's families on the headline metrics, with
the interval its seeds allow (docs/STATISTICS.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Optional

import pandas as pd

from hnnbench._results import stats
from hnnbench._results.aggregate import headline_metrics
from hnnbench._results.families import RANKING_KEY, ROW_KEY, key_of, primary_rows, select
from hnnbench._results.leaderboard import (
    format_interval,
)

__all__ = ["Rank", "rank_lines"]


def _interval_of(row: Any, metric: str) -> Optional[tuple[float, float]]:
    low, high = row.get(f"{metric}_ci_low"), row.get(f"{metric}_ci_high")
    if low is None or high is None or pd.isna(low) or pd.isna(high):
        return None
    return float(low), float(high)


def _ordinal_text(low: int, high: int) -> str:
    return f"[{low}, {high}]" if low != high else f"[{low}]"


@dataclass
class Rank:
    """One new family's rank on one (system, metric) among the reference's families."""

    name: str
    system: str
    metric: str
    rank: int
    of: int
    low: Optional[int]  # the rank interval (None: no interval)
    high: Optional[int]
    line: str


def _rank_one(
    name: str, row: Any, others: pd.DataFrame, metric: str, better: str, linear: bool
) -> Optional[Rank]:
    value = pd.to_numeric(row.get(f"{metric}_mean"), errors="coerce")
    system = str(row["system"])
    if pd.isna(value):
        return None
    value = float(value)
    means = pd.to_numeric(others[f"{metric}_mean"], errors="coerce")
    others = others[means.notna()]
    means = means[means.notna()].astype(float)
    sign = -1.0 if better == "higher" else 1.0
    rank = 1 + int((sign * means < sign * value).sum())
    of = len(others) + 1
    mine = _interval_of(row, metric)
    if mine is None and math.isinf(value):
        mine = (value, value)  # a diverged mean: certainly there
    theirs = []
    for _, r in others.iterrows():
        interval, mean = _interval_of(r, metric), float(r[f"{metric}_mean"])
        theirs.append(
            interval if interval is not None else (mean, mean) if math.isinf(mean) else None
        )
    n_seeds = int(row.get("n_seeds", 0) or 0)
    shown = format_interval(
        value, *(_interval_of(row, metric) or (math.nan, math.nan)), linear=linear
    )
    low = high = None
    if mine is None:
        text = (
            f"({n_seeds} seed: no interval)"
            if n_seeds < 2
            else "(fewer than 2 seeds with a value: no interval)"
        )
    elif all(t is None for t in theirs):
        n_ref = int(pd.to_numeric(others["n_seeds"], errors="coerce").min())
        text = (
            f"(the reference has {n_ref} seed{'s' if n_ref != 1 else ''} and no "
            "interval: no rank interval)"
        )
    else:
        # a reference family without an interval is separated from no one
        lo_m, hi_m = sorted((sign * mine[0], sign * mine[1]))
        ahead = behind = 0
        for t in theirs:
            if t is None:
                continue
            lo_t, hi_t = sorted((sign * t[0], sign * t[1]))
            ahead += hi_t < lo_m  # wholly better than ours
            behind += lo_t > hi_m  # wholly worse
        low, high = 1 + ahead, of - behind
        text = _ordinal_text(low, high)
    line = (
        f"{system} {metric}: {name} ranks {rank} of {of} families {text}: {shown} over "
        f"{n_seeds} seed{'s' if n_seeds != 1 else ''}"
    )
    return Rank(name, system, metric, rank, of, low, high, line)


def _verdict(name: str, ranks: list[Rank]) -> str:
    if not ranks:
        return f"verdict: {name} has no value on a headline metric here"
    first = sum(r.rank == 1 for r in ranks)
    top = sum(r.rank <= (r.of + 1) // 2 for r in ranks)
    median = sorted(r.rank for r in ranks)[(len(ranks) - 1) // 2]
    of = max(r.of for r in ranks)
    text = (
        f"verdict: {name} ranks first on {first} and in the top half on {top} of "
        f"{len(ranks)} (system, metric) cell(s), median rank {median} of {of}"
    )
    with_interval = [r for r in ranks if r.low is not None]
    if not with_interval:
        return (
            text + "; no rank is backed by an interval (an interval needs 2 seeds on "
            f"both sides; a separated best, {stats.MIN_SEPARABLE_SEEDS} paired seeds)"
        )
    sure = sum(r.high == 1 for r in with_interval)
    maybe = sum(r.low == 1 for r in with_interval)
    return (
        text + f"; the intervals put it first on {sure} and possibly first on {maybe} "
        f"of the {len(with_interval)} with an interval"
    )


def rank_lines(
    reference: pd.DataFrame, current: pd.DataFrame, metrics: Optional[Sequence[str]] = None
) -> list[str]:
    """For every family of ``current`` that the reference does not hold (a new model,
    or a variant), per system and headline metric (default:
    :func:`hnnbench._results.aggregate.headline_metrics`): its rank among the reference's ranked
    families on that system (by mean), the rank interval their intervals allow (each
    family's 95% interval over seeds, ``<metric>_ci_low``/``_ci_high``: ranked ahead of
    it are the families whose interval lies wholly on the better side), and then one
    verdict line per new family."""
    from hnnbench._results.leaderboard import linear_metrics, metric_declarations

    declared = metric_declarations()
    metrics = [
        m
        for m in (headline_metrics() if metrics is None else metrics)
        if m in declared and f"{m}_mean" in current and f"{m}_mean" in reference
    ]
    if current.empty:
        return []
    linear = linear_metrics()

    def ranked(frame: pd.DataFrame) -> pd.DataFrame:
        frame = frame[frame["ranked"].fillna(True).astype(str).str.lower() != "false"]
        return primary_rows(frame)

    ref, cur = ranked(reference), ranked(current)
    keys = {key_of(r, ROW_KEY) for _, r in ref.iterrows()}
    ranking = [k for k in RANKING_KEY if k != "variant"]
    lines: list[str] = []
    by_name: dict[str, list[Rank]] = {}
    for _, row in cur.iterrows():
        if key_of(row, ROW_KEY) in keys:
            continue
        name = str(row["seeds_from"]) + (f" [{row['variant']}]" if row["variant"] else "")
        others = select(ref, [*ranking, "variant"], (*key_of(row, ranking), ""))
        by_name.setdefault(name, [])
        if others.empty:
            continue
        for metric in metrics:
            done = _rank_one(name, row, others, metric, declared[metric].better, metric in linear)
            if done is not None:
                lines.append(done.line)
                by_name[name].append(done)
    lines += [_verdict(name, ranks) for name, ranks in by_name.items()]
    return lines
