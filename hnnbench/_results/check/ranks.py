"""A new model's rank on the headline metrics, with the interval its seeds allow
(docs/STATISTICS.md, "A new model in hnnbench check"): among the reference's families
on its system, or, where the reference has no rows for that system, among the families
run beside it in the same sweep (then with the leader test over their paired seeds);
and, where it cannot be ranked, one line saying why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Optional

import pandas as pd

from hnnbench._contracts.names import STANDING_STILL
from hnnbench._results import stats
from hnnbench._results.aggregate import headline_metrics
from hnnbench._results.families import (
    RANKING_KEY,
    ROW_KEY,
    TOO_FEW,
    families,
    family_order,
    key_of,
    primary_rows,
    select,
)
from hnnbench._results.leaderboard import format_interval, text_column

__all__ = ["BESIDE", "REFERENCE", "Rank", "Ranking", "rank_lines", "ranking"]

#: What a rank is among: the reference's families on its system, or the families run
#: beside it in the checked sweep (the reference has no rows for its system).
REFERENCE, BESIDE = "reference", "beside"


def _interval_of(row: Any, metric: str) -> Optional[tuple[float, float]]:
    low, high = row.get(f"{metric}_ci_low"), row.get(f"{metric}_ci_high")
    if low is None or high is None or pd.isna(low) or pd.isna(high):
        return None
    return float(low), float(high)


def _ordinal_text(low: int, high: int) -> str:
    return f"[{low}, {high}]" if low != high else f"[{low}]"


@dataclass
class Rank:
    """One new family's rank on one (system, metric): among the reference's families
    (``basis`` :data:`REFERENCE`) or the families run beside it (:data:`BESIDE`, with
    ``leader_test``: what the leader test over the sweep's paired seeds says)."""

    name: str
    system: str
    metric: str
    rank: int
    of: int
    low: Optional[int]  # the rank interval (None: no interval)
    high: Optional[int]
    line: str
    basis: str = REFERENCE
    against: tuple[str, ...] = ()  # the families ranked against (their primary models)
    n_seeds: int = 0
    mean: float = math.nan
    ci_low: float = math.nan
    ci_high: float = math.nan
    leader_test: str = ""
    value_text: str = ""  # the mean and its interval, as the line shows them


def _rank_one(
    name: str,
    row: Any,
    others: pd.DataFrame,
    metric: str,
    better: str,
    linear: bool,
    basis: str = REFERENCE,
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
        whose = "the reference has" if basis == REFERENCE else "the families beside it have"
        text = (
            f"({whose} {n_ref} seed{'s' if n_ref != 1 else ''} and no interval: no rank interval)"
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
    interval = _interval_of(row, metric) or (math.nan, math.nan)
    against = tuple(str(r.get("seeds_from", r["model"])) for _, r in others.iterrows())
    return Rank(
        name,
        system,
        metric,
        rank,
        of,
        low,
        high,
        line,
        basis,
        against,
        n_seeds,
        value,
        *interval,
        value_text=shown,
    )


def _verdict(name: str, ranks: list[Rank]) -> str:
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


@dataclass
class Ranking:
    """What :func:`ranking` found: every rank, one verdict per ranked family, and the
    lines in the order they are printed (each family's basis, its ranks, the reasons it
    cannot be ranked where it cannot, then the verdicts)."""

    ranks: list[Rank] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what a family is ranked against
    verdicts: dict[str, str] = field(default_factory=dict)
    reasons: dict[str, list[str]] = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)


def _scope_text(row: Any, reference: pd.DataFrame) -> str:
    """Which rows the reference lacks: its system's, or those of its profile and track
    on that system."""
    system = str(row["system"])
    if reference.empty or system not in set(reference["system"].astype(str)):
        return f"system {system}"
    keys = [k for k in RANKING_KEY if k not in ("system", "variant")]
    wanted = ", ".join(f"{k} {v}" for k, v in zip(keys, key_of(row, keys), strict=True))
    return f"system {system} with {wanted}"


def _suggestion(reference: pd.DataFrame, name: str, system: str) -> str:
    """A command that gives ``name`` a rank on ``system``: the reference's first two
    families (their primary models) beside it, over the fewest paired seeds with which
    the leader test can separate the leader from the other two."""
    models: list[str] = []
    if not reference.empty:
        fams = primary_rows(reference)
        order = family_order(fams) if "models" in fams else []
        by_family = {str(r["family"]): str(r["seeds_from"]) for _, r in fams.iterrows()}
        models = [by_family[f] for f in order if f in by_family][:2]
    if not models:
        return "run a baseline family beside it over the same seeds"
    n = stats.min_separable_seeds(comparisons=len(models))
    seeds = ",".join(str(s) for s in range(n))
    return (
        f"run e.g. -m system={system} model={name},{','.join(models)} seed={seeds} "
        f"({n} paired seeds: the fewest with which the sign test can separate a leader "
        f"from {len(models)} other famil{'ies' if len(models) > 1 else 'y'})"
    )


def _leader_text(board: pd.DataFrame, row: Any, metric: str, others: int) -> str:
    """What the leader test over the sweep's paired seeds says of ``row``'s family on
    ``metric`` among the families beside it (``board``: their family rows, marked)."""
    cell = select(board, list(RANKING_KEY), key_of(row, RANKING_KEY))
    column = f"{metric}_mark"
    if cell.empty or column not in cell:
        return "not applied"
    marks = text_column(cell, column)
    mine = cell[cell["family"].astype(str) == str(row["family"])]
    mark = str(mine[column].iloc[0]) if not mine.empty else ""
    if (marks == TOO_FEW).any():
        needed = stats.min_separable_seeds(comparisons=max(1, others))
        seeds = int(row.get("n_seeds", 0) or 0)
        return (
            f"too few seeds to separate ({seeds} seed{'s' if seeds != 1 else ''}; the "
            f"sign test needs {needed} paired seeds against {others} other "
            f"famil{'ies' if others != 1 else 'y'}): no best"
        )
    if str(row.get("variant") or ""):
        return "not applied (a variant is tested among the rows of its own variant)"
    if mark == "best":
        p = float(mine[f"{metric}_p"].iloc[0])
        return f"best (paired sign test, Holm-adjusted p = {p:.3g})"
    leader = cell[marks.isin(["best", "tied"])]
    if mark == "tied":
        return "tied for first (not separated by the paired sign test)"
    if not leader.empty:
        p = mine[f"{metric}_p"].iloc[0] if not mine.empty else math.nan
        return (
            "separated from the leader by the paired sign test"
            + (f" (Holm-adjusted p = {float(p):.3g})" if not pd.isna(p) else "")
            + ": not first"
        )
    from hnnbench._results.leaderboard import metric_declarations

    if (
        metric_declarations()[metric].beat_reference
        and not (text_column(cell, "reference") == STANDING_STILL).any()
    ):
        return (
            "not applied (marked only where the leader beats the standing-still "
            "reference, and none ran beside it)"
        )
    return "not applied (no family may lead on this metric here)"


def ranking(
    reference: pd.DataFrame,
    current: pd.DataFrame,
    metrics: Optional[Sequence[str]] = None,
    frame: Optional[pd.DataFrame] = None,
) -> Ranking:
    """Every family of ``current`` that the reference does not hold (a new model, a
    variant, or any family on a system the reference has no rows for), per system and
    headline metric (default: :func:`hnnbench._results.aggregate.headline_metrics`): its
    rank by mean and the rank interval the 95% intervals over seeds allow (ranked ahead
    of it are the families whose interval lies wholly on the better side).

    It is ranked among the reference's ranked families on its system; where the
    reference has none there, among the ranked families run beside it in ``current``
    (on a system new to the reference, the families the reference knows elsewhere are
    the comparators of those it does not; if it knows them all, each is ranked against
    the others), with the leader test over their paired seeds (``frame``: the sweep's
    records frame; docs/STATISTICS.md, "Best and tied"). Where neither exists, one line
    says why it has no rank and what to run."""
    from hnnbench._results.leaderboard import linear_metrics, metric_declarations

    declared = metric_declarations()
    metrics = [
        m
        for m in (headline_metrics() if metrics is None else metrics)
        if m in declared and f"{m}_mean" in current
    ]
    out = Ranking()
    if current.empty:
        return out
    linear = linear_metrics()

    def ranked(board: pd.DataFrame) -> pd.DataFrame:
        if board.empty:
            return board
        board = board[board["ranked"].fillna(True).astype(str).str.lower() != "false"]
        return primary_rows(board)

    ref, cur = ranked(reference), ranked(current)
    keys = {key_of(r, ROW_KEY) for _, r in ref.iterrows()}
    known = set(ref["family"].astype(str)) if not ref.empty else set()
    ranking_keys = [k for k in RANKING_KEY if k != "variant"]
    marked: Optional[pd.DataFrame] = None

    def marks() -> pd.DataFrame:
        nonlocal marked
        if marked is None:
            marked = families(frame, current).board if frame is not None else pd.DataFrame()
        return marked

    def rank_all(name: str, row: Any, others: pd.DataFrame, basis: str) -> list[Rank]:
        done = []
        for metric in metrics:
            if f"{metric}_mean" not in others:
                continue
            rank = _rank_one(
                name, row, others, metric, declared[metric].better, metric in linear, basis
            )
            if rank is None:
                continue
            if basis == BESIDE:
                rank.leader_test = _leader_text(marks(), row, metric, len(others))
                rank.line += f"; leader test: {rank.leader_test}"
            done.append(rank)
        return done

    by_name: dict[str, list[Rank]] = {}
    for _, row in cur.iterrows():
        if key_of(row, ROW_KEY) in keys:
            continue
        name = str(row["seeds_from"]) + (f" [{row['variant']}]" if row["variant"] else "")
        scope = (*key_of(row, ranking_keys), "")
        others = select(ref, [*ranking_keys, "variant"], scope) if not ref.empty else ref
        if not others.empty:
            got = rank_all(name, row, others, REFERENCE)
            by_name.setdefault(name, []).extend(got)
            out.lines += [r.line for r in got]
            continue
        beside = select(cur, [*ranking_keys, "variant"], scope)
        beside = beside[beside["family"].astype(str) != str(row["family"])]
        new_here = set(beside["family"].astype(str)) - known
        if str(row["family"]) in known and new_here:
            continue  # a comparator of the new families beside it, not a submission
        system = str(row["system"])
        where = _scope_text(row, reference if not reference.empty else ref)
        if beside.empty:
            reason = (
                f"no rank for {name} on {system}: the reference has no rows for {where} "
                f"and no other family ran beside it on {system}; "
                f"{_suggestion(ref, name, system)}"
            )
            out.reasons.setdefault(name, []).append(reason)
            out.lines.append(reason)
            continue
        against = [str(r["seeds_from"]) for _, r in beside.iterrows()]
        note = (
            f"{system}: the reference has no rows for {where}; {name} ranked against the "
            f"families run beside it: {', '.join(against)}"
        )
        out.notes.append(note)
        out.lines.append(note)
        got = rank_all(name, row, beside, BESIDE)
        by_name.setdefault(name, []).extend(got)
        out.lines += [r.line for r in got]
    for name, ranks in by_name.items():
        out.ranks += ranks
        if ranks:
            out.verdicts[name] = _verdict(name, ranks)
        elif name not in out.reasons:
            out.verdicts[name] = f"verdict: {name} has no value on a headline metric here"
    out.lines += list(out.verdicts.values())
    return out


def rank_lines(
    reference: pd.DataFrame,
    current: pd.DataFrame,
    metrics: Optional[Sequence[str]] = None,
    frame: Optional[pd.DataFrame] = None,
) -> list[str]:
    """:func:`ranking`'s lines, in the order they are printed."""
    return ranking(reference, current, metrics, frame).lines
