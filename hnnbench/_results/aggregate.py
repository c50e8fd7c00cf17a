"""The verdict across systems: per family and metric a score normalised per system, its
interquartile mean over every (system, seed) run with a stratified bootstrap interval,
P(A > B) and performance profiles (Agarwal et al. 2021; docs/STATISTICS.md, "Across
systems"). The statistics themselves are :mod:`hnnbench._results.stats`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import combinations
from typing import Optional

import numpy as np
import pandas as pd

from hnnbench import _registry as registry
from hnnbench._contracts.metric import CheckRule
from hnnbench._contracts.names import STANDING_STILL
from hnnbench._results import stats
from hnnbench._results.families import SCOPE_KEY, Families, family_order, key_of, scope_name, select
from hnnbench._results.leaderboard import flag_column, metric_declarations, text_column

__all__ = ["Aggregate", "aggregate", "headline_metrics", "profile_taus"]

#: Points of a performance profile.
N_TAUS = 81


def profile_taus(scores: np.ndarray) -> np.ndarray:
    """The thresholds of a performance profile: from the 2nd percentile of the scores
    (at least -1) to their largest (at most the floor's 1), on a 0.1 grid."""
    finite = scores[np.isfinite(scores)]
    if not finite.size:
        return np.linspace(-1.0, 1.0, N_TAUS)
    low = max(-1.0, math.floor(float(np.quantile(finite, 0.02)) * 10) / 10)
    high = min(1.0, math.ceil(float(np.max(finite)) * 10) / 10)
    return np.linspace(low, max(high, low + 0.1), N_TAUS)


SCALE_COLUMNS = [
    *SCOPE_KEY,
    "metric",
    "system",
    "baseline",
    "floor",
    "floor_from",
    "used",
    "why_not",
]
IQM_COLUMNS = [
    *SCOPE_KEY,
    "metric",
    "family",
    "iqm",
    "iqm_low",
    "iqm_high",
    "n_systems",
    "n_runs",
    "systems",
]
IMPROVEMENT_COLUMNS = [
    *SCOPE_KEY,
    "metric",
    "family",
    "other",
    "p",
    "p_low",
    "p_high",
    "n_systems",
    "min_seeds",
    "claimable",
]
RANK_COLUMNS = [
    *SCOPE_KEY,
    "metric",
    "family",
    "mean_rank",
    "rank_low",
    "rank_high",
    "n_families",
    "n_systems",
    "systems",
    "left_out",
]
#: The second floor the secondary (normalised) view is also computed with: this share of
#: the best family's mean on the system (lower-is-better metrics), to show how much the
#: order hangs on the floor.
ALT_FLOOR_SHARE = 0.5
#: Bootstrap resamples of the mean rank's interval.
RANK_RESAMPLES = 2000


def headline_metrics() -> list[str]:
    """The installed metrics declared ``headline`` (:attr:`hnnbench.Metric.headline`),
    in table order."""
    return [m.name for m in registry.metrics() if m.headline and m.ranked]


@dataclass
class Aggregate:
    """The aggregate of a family view, per scope (:data:`hnnbench._results.families.SCOPE_KEY`:
    the profile; one aggregate never mixes two).

    Attributes:
        iqm: per (scope, metric, family): ``iqm`` and its interval ``iqm_low``,
            ``iqm_high``, ``n_systems``, ``n_runs``, ``systems`` (``;``-joined).
        improvement: per (scope, metric, family, other), both orders: ``p`` =
            P(a run of ``family`` is better than one of ``other`` on the same system,
            from the metric's values: no normalisation), its interval ``p_low``,
            ``p_high``, ``n_systems`` (both ran), ``min_seeds`` (the fewest runs either
            has on one of them) and ``claimable`` (``min_seeds`` reaches
            :data:`hnnbench._results.stats.MIN_SEPARABLE_SEEDS`: only then may a report say one
            beats the other).
        ranks: per (scope, metric, family): the headline, free of any normalisation:
            the family's rank among the ranked families on each (system, seed) (1 =
            best; a run without a finite value last; ties share the mean rank), averaged
            over the seeds and then over the systems every family of the scope ran
            (``systems``; ``left_out``: the systems some family did not run), with a
            stratified bootstrap interval (seeds resampled within each system).
        scales: per (scope, metric, system): ``baseline``, ``floor``, ``floor_from``,
            ``used`` and, where not used, ``why_not``.
        scores: per (scope, metric, system, family, seed): ``score``.
        profiles: ``{(scope, metric): (taus, {family: (fraction, low, high)})}`` (the
            scope's values joined by ``/``)
            (:func:`profile_taus`; :func:`hnnbench._results.stats.performance_profile`).
        baseline: the baseline family, or ``None``.
        note: why there is no aggregate, if there is none.
    """

    iqm: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=IQM_COLUMNS))
    improvement: pd.DataFrame = field(
        default_factory=lambda: pd.DataFrame(columns=IMPROVEMENT_COLUMNS)
    )
    scales: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=SCALE_COLUMNS))
    scores: pd.DataFrame = field(default_factory=pd.DataFrame)
    profiles: dict[
        tuple[str, str], tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]]
    ] = field(default_factory=dict)
    ranks: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=RANK_COLUMNS))
    #: per (scope, metric): the IQM order of the families under the floor of
    #: :data:`ALT_FLOOR_SHARE` (``;``-joined, best first), and under the main floor
    orders: dict[tuple[str, str], tuple[list[str], list[str]]] = field(default_factory=dict)
    baseline: Optional[str] = None
    note: str = ""

    @property
    def empty(self) -> bool:
        return self.iqm.empty and self.ranks.empty


def _floor(rows: pd.DataFrame, metric: str, rule: CheckRule) -> tuple[float, str]:
    """The floor of one (system, metric) and where it comes from."""
    refs = rows[~flag_column(rows, "ranked", True)]
    # standing still is a reference to beat, never the floor
    refs = refs[text_column(refs, "reference") != STANDING_STILL]
    values = pd.to_numeric(refs.get(f"{metric}_mean", pd.Series(dtype=float)), errors="coerce")
    values = values[np.isfinite(values)]
    if len(values):
        i = values.idxmax() if rule.better == "higher" else values.idxmin()
        best = float(values[i])
        if rule.better == "lower" and best < rule.floor:
            return rule.floor, f"noise floor (the {refs.at[i, 'family']} is below it)"
        return best, str(refs.at[i, "family"])
    if rule.floor > 0:
        return rule.floor, "noise floor (no reference model ran)"
    return math.nan, "no reference model ran, and the metric declares no noise floor"


def _runs(
    fams: Families, scope: tuple[str, ...], system: str, family: str, metric: str
) -> tuple[np.ndarray, np.ndarray]:
    """A family's seeds and per-seed values on a system (skipped runs left out)."""
    sel = select(fams.runs, SCOPE_KEY, scope)
    sel = sel[(sel["system"] == system) & (sel["family"] == family)]
    sel = sel[text_column(sel, "variant") == ""]
    sel = sel[sel["status"] != "skipped"]
    values = (
        pd.to_numeric(sel[metric], errors="coerce")
        if metric in sel
        else pd.Series(math.nan, index=sel.index)
    )
    return sel["seed"].to_numpy(), values.to_numpy(dtype=float)


def aggregate(
    fams: Families,
    metrics: Optional[Sequence[str]] = None,
    improvement_metrics: Optional[Sequence[str]] = None,
) -> Aggregate:
    """The aggregate (:class:`Aggregate`) of ``fams`` over ``metrics`` (default: every
    ranked metric of the board); probabilities of improvement and performance profiles
    over ``improvement_metrics`` (default: :func:`headline_metrics`)."""
    declared = metric_declarations()
    board = fams.board
    if board.empty:
        return Aggregate(note="no records")
    board = board[text_column(board, "variant") == ""]
    present = [c[:-5] for c in board.columns if c.endswith("_mean")]
    if metrics is None:
        metrics = [m for m in present if m in declared and declared[m].ranked]
    metrics = [m for m in metrics if m in present and m in declared]
    if improvement_metrics is None:
        improvement_metrics = headline_metrics()
    baselines = registry.baseline_families()
    if not baselines:
        return Aggregate(
            note="no installed model family declares itself the baseline "
            "(hnnbench.neural.Family(baseline=True))"
        )
    if len(baselines) > 1:
        return Aggregate(
            note=f"several families declare themselves the baseline "
            f"({', '.join(baselines)}); exactly one may"
        )
    baseline = baselines[0]
    order = family_order(board)
    scales, scores = [], []
    for _, mine in board.groupby(list(SCOPE_KEY), sort=False, dropna=False):
        scope = key_of(mine.iloc[0], SCOPE_KEY)
        where = dict(zip(SCOPE_KEY, scope, strict=True))
        for metric in metrics:
            rule = declared[metric].check
            for system in registry.ordered("system", mine["system"].astype(str)):
                rows = mine[mine["system"] == system]
                values = pd.to_numeric(rows[f"{metric}_mean"], errors="coerce")
                if values.isna().all():
                    continue  # not applicable on this system
                base_rows = rows[rows["family"] == baseline]
                base = (
                    float(pd.to_numeric(base_rows[f"{metric}_mean"], errors="coerce").iloc[0])
                    if len(base_rows)
                    else math.nan
                )
                floor, source = _floor(rows, metric, rule)
                scale = stats.normalisation_scale(base, floor, rule)
                why = (
                    ""
                    if scale is not None
                    else (
                        f"no {baseline} (baseline) value"
                        if math.isnan(base)
                        else f"{baseline} (baseline) is not finite"
                        if not math.isfinite(base)
                        else source
                        if math.isnan(floor)
                        else f"{baseline} (baseline) is within the metric's tolerance "
                        f"({rule.factor:g}x) of the floor"
                    )
                )
                scales.append(
                    {
                        **where,
                        "metric": metric,
                        "system": system,
                        "baseline": base,
                        "floor": floor,
                        "floor_from": source,
                        "used": scale is not None,
                        "why_not": why,
                    }
                )
                if scale is None:
                    continue
                for family in rows[flag_column(rows, "ranked", True)]["family"]:
                    seeds, runs = _runs(fams, scope, system, str(family), metric)
                    if not len(runs):
                        continue
                    normalised = stats.normalised_scores(runs, base, floor, rule)
                    assert normalised is not None
                    scores += [
                        {
                            **where,
                            "metric": metric,
                            "system": system,
                            "family": str(family),
                            "seed": int(seed),
                            "score": float(v),
                        }
                        for seed, v in zip(seeds, normalised, strict=True)
                    ]
    scores_frame = pd.DataFrame(
        scores, columns=[*SCOPE_KEY, "metric", "system", "family", "seed", "score"]
    )
    out = Aggregate(
        scales=pd.DataFrame(scales, columns=SCALE_COLUMNS), scores=scores_frame, baseline=baseline
    )
    if scores_frame.empty:
        out.note = "no (system, metric) with a scale: every one lacks a baseline or a floor"
        return out
    iqm_rows, poi_rows = [], []
    for key, group in scores_frame.groupby([*SCOPE_KEY, "metric"], sort=False):
        *names, metric = (str(k) for k in key)
        where = dict(zip(SCOPE_KEY, names, strict=True))
        strata: dict[str, dict[str, np.ndarray]] = {}
        for (family, system), g in group.groupby(["family", "system"], sort=False):
            strata.setdefault(str(family), {})[str(system)] = g["score"].to_numpy(float)
        families = [f for f in order if f in strata]
        for family in families:
            point, low, high = stats.stratified_interval(list(strata[family].values()))
            iqm_rows.append(
                {
                    **where,
                    "metric": metric,
                    "family": family,
                    "iqm": point,
                    "iqm_low": low,
                    "iqm_high": high,
                    "n_systems": len(strata[family]),
                    "n_runs": int(sum(v.size for v in strata[family].values())),
                    "systems": ";".join(strata[family]),
                }
            )
        taus = profile_taus(group["score"].to_numpy(float))
        label = scope_name(names)
        out.profiles[(label, metric)] = (
            taus,
            {
                family: stats.performance_profile(list(strata[family].values()), taus)
                for family in families
            },
        )
    out.iqm = pd.DataFrame(iqm_rows, columns=IQM_COLUMNS)
    rank_rows: list[dict[str, object]] = []
    for _, mine in board.groupby(list(SCOPE_KEY), sort=False, dropna=False):
        scope = key_of(mine.iloc[0], SCOPE_KEY)
        where = dict(zip(SCOPE_KEY, scope, strict=True))
        for metric in improvement_metrics:
            if metric not in declared or f"{metric}_mean" not in mine:
                continue
            values = _raw_values(fams, scope, mine, metric, order)
            if not values:
                continue
            rank_rows += _ranks(values, declared[metric].better, where, metric)
            poi_rows += _improvements(values, declared[metric].better, where, metric)
            moved = _alt_order(fams, scope, mine, metric, declared[metric].check, baseline, order)
            if moved is not None:
                out.orders[(scope_name(scope), metric)] = moved
    out.ranks = pd.DataFrame(rank_rows, columns=RANK_COLUMNS)
    out.improvement = pd.DataFrame(poi_rows, columns=IMPROVEMENT_COLUMNS)
    return out


Values = dict[str, dict[str, dict[int, float]]]  # system -> family -> seed -> value


def _raw_values(
    fams: Families, scope: tuple[str, ...], board: pd.DataFrame, metric: str, order: list[str]
) -> Values:
    """Every ranked family's per-seed values of ``metric`` on each system where it
    applies (a family row with a finite or infinite mean): ``{system: {family: {seed:
    value}}}``."""
    out: Values = {}
    for system in registry.ordered("system", board["system"].astype(str)):
        rows = board[(board["system"] == system) & flag_column(board, "ranked", True)]
        means = pd.to_numeric(rows[f"{metric}_mean"], errors="coerce")
        if means.isna().all():
            continue
        per: dict[str, dict[int, float]] = {}
        for family in [f for f in order if f in set(rows["family"].astype(str))]:
            seeds, runs = _runs(fams, scope, system, family, metric)
            if len(runs):
                per[family] = {int(k): float(v) for k, v in zip(seeds, runs, strict=True)}
        if len(per) >= 2:
            out[system] = per
    return out


def _badness(value: float, better: str) -> float:
    """A value as a cost (lower is better), a run without a finite value the worst."""
    if not math.isfinite(value):
        return math.inf
    return value if better == "lower" else -value


def _ranks(
    values: Values, better: str, where: dict[str, str], metric: str
) -> list[dict[str, object]]:
    """The mean rank rows (:attr:`Aggregate.ranks`) of one (scope, metric)."""
    families = list(dict.fromkeys(f for per in values.values() for f in per))
    common = [s for s, per in values.items() if all(f in per for f in families)]
    left_out = [s for s in values if s not in common]
    if not common:
        return []
    tables = []  # per system: (seeds, families) ranks
    for system in common:
        per = values[system]
        seeds = sorted(set.intersection(*(set(per[f]) for f in families)))
        if not seeds:
            return []
        costs = np.array([[_badness(per[f][k], better) for f in families] for k in seeds])
        tables.append(np.apply_along_axis(_rank_row, 1, costs))
    point = np.mean([t.mean(axis=0) for t in tables], axis=0)
    rng = np.random.default_rng(stats.BOOTSTRAP_SEED)
    draws = np.empty((RANK_RESAMPLES, len(families)))
    for b in range(RANK_RESAMPLES):
        draws[b] = np.mean(
            [t[rng.integers(0, len(t), len(t))].mean(axis=0) for t in tables], axis=0
        )
    tail = (1.0 - stats.CONFIDENCE) / 2.0
    low, high = np.quantile(draws, tail, axis=0), np.quantile(draws, 1.0 - tail, axis=0)
    return [
        {
            **where,
            "metric": metric,
            "family": f,
            "mean_rank": float(point[j]),
            "rank_low": float(low[j]),
            "rank_high": float(high[j]),
            "n_families": len(families),
            "n_systems": len(common),
            "systems": ";".join(common),
            "left_out": ";".join(left_out),
        }
        for j, f in enumerate(families)
    ]


def _rank_row(costs: np.ndarray) -> np.ndarray:
    """Ranks of one seed's costs (1 = lowest; ties, infinities included, share the mean
    rank)."""
    from scipy.stats import rankdata

    return np.asarray(rankdata(np.where(np.isinf(costs), np.finfo(float).max, costs)), dtype=float)


def _improvements(
    values: Values, better: str, where: dict[str, str], metric: str
) -> list[dict[str, object]]:
    """P(A better than B) rows (:attr:`Aggregate.improvement`) of one (scope, metric),
    from the values themselves: over the systems both ran, each system's runs of A
    against its runs of B (a tie counts one half)."""
    families = list(dict.fromkeys(f for per in values.values() for f in per))
    rows: list[dict[str, object]] = []
    for a, b in combinations(families, 2):
        common = [s for s, per in values.items() if a in per and b in per]
        if not common:
            continue
        goods = [
            [-_badness(v, better) for v in values[s][f].values()] for f in (a, b) for s in common
        ]
        xs, ys = goods[: len(common)], goods[len(common) :]
        p, low, high = stats.probability_of_improvement(
            [np.nan_to_num(np.asarray(x), neginf=-np.finfo(float).max) for x in xs],
            [np.nan_to_num(np.asarray(y), neginf=-np.finfo(float).max) for y in ys],
        )
        fewest = min(min(len(values[s][a]), len(values[s][b])) for s in common)
        claim = fewest >= stats.MIN_SEPARABLE_SEEDS
        rows.append(
            {
                **where,
                "metric": metric,
                "family": a,
                "other": b,
                "p": p,
                "p_low": low,
                "p_high": high,
                "n_systems": len(common),
                "min_seeds": fewest,
                "claimable": claim,
            }
        )
        rows.append(
            {
                **where,
                "metric": metric,
                "family": b,
                "other": a,
                "p": 1.0 - p,
                "p_low": 1.0 - high,
                "p_high": 1.0 - low,
                "n_systems": len(common),
                "min_seeds": fewest,
                "claimable": claim,
            }
        )
    return rows


def _alt_order(
    fams: Families,
    scope: tuple[str, ...],
    board: pd.DataFrame,
    metric: str,
    rule: CheckRule,
    baseline: str,
    order: list[str],
) -> Optional[tuple[list[str], list[str]]]:
    """The families' IQM order under the main floor and under a second one
    (:data:`ALT_FLOOR_SHARE` of the best ranked family's mean on each system), best
    first; ``None`` for a higher-is-better metric or where no system has a scale."""
    if rule.better != "lower":
        return None
    orders = []
    for alt in (False, True):
        strata: dict[str, list[np.ndarray]] = {}
        for system in registry.ordered("system", board["system"].astype(str)):
            rows = board[board["system"] == system]
            means = pd.to_numeric(rows[f"{metric}_mean"], errors="coerce")
            ranked = rows[flag_column(rows, "ranked", True)]
            base_rows = rows[rows["family"] == baseline]
            if means.isna().all() or base_rows.empty:
                continue
            base = float(pd.to_numeric(base_rows[f"{metric}_mean"], errors="coerce").iloc[0])
            if alt:
                finite = pd.to_numeric(ranked[f"{metric}_mean"], errors="coerce")
                finite = finite[np.isfinite(finite)]
                if finite.empty:
                    continue
                floor = ALT_FLOOR_SHARE * float(finite.min())
            else:
                floor, _ = _floor(rows, metric, rule)
            if stats.normalisation_scale(base, floor, rule) is None:
                continue
            for family in ranked["family"].astype(str):
                _, runs = _runs(fams, scope, system, family, metric)
                scores = stats.normalised_scores(runs, base, floor, rule) if len(runs) else None
                if scores is not None:
                    strata.setdefault(family, []).append(scores)
        if not strata:
            return None
        points = {f: float(stats.iqm(np.concatenate(v))) for f, v in strata.items()}
        orders.append(
            sorted(points, key=lambda f: (-points[f], order.index(f) if f in order else 0))
        )
    return orders[0], orders[1]
