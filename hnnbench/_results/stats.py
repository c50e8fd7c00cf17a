"""The statistics behind every verdict, declared once (docs/STATISTICS.md): a cell's
interval over seeds, the leader test (two-sided paired sign tests, Holm-adjusted), the
leader's paired effect size, and the aggregate's normalised scores, IQM,
stratified intervals, P(A > B) and performance profiles. Every table, figure, the
aggregate and ``hnnbench check`` read these; none computes its own. Pure numpy and scipy.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Any, Optional

import numpy as np

from hnnbench._contracts.metric import CheckRule

__all__ = [
    "AGGREGATE_METHOD",
    "ALPHA",
    "BOOTSTRAP_SEED",
    "CELL_METHOD",
    "CONFIDENCE",
    "IQM_CUT",
    "MIN_SEPARABLE_SEEDS",
    "N_RESAMPLES",
    "SCORE_RANGE",
    "aggregate_rule",
    "best_rule",
    "rank_rule",
    "cell_rule",
    "holm",
    "iqm",
    "leader_test",
    "paired_leader_test",
    "mean_intervals",
    "min_separable_seeds",
    "normalisation_scale",
    "normalised_scores",
    "paired_effect",
    "performance_profile",
    "probability_of_improvement",
    "sign_test",
    "stratified_interval",
]

#: The confidence of every interval.
CONFIDENCE = 0.95
#: The level of the paired test that separates a best value from the others.
ALPHA = 0.05
#: Bootstrap resamples of every interval, and the seed they are drawn from.
N_RESAMPLES = 9999
BOOTSTRAP_SEED = 2021
#: ``scipy.stats.bootstrap`` methods: a cell (the mean over one pair's seeds: bias- and
#: skew-corrected, for a mean that one seed can dominate) and the aggregate across systems
#: (the percentile interval of rliable and Agarwal et al. 2021).
CELL_METHOD = "BCa"
AGGREGATE_METHOD = "percentile"
#: The share cut from each end for the interquartile mean.
IQM_CUT = 0.25
#: Normalised scores are clipped to this range; a run without a finite value (diverged,
#: failed) scores the lower end.
SCORE_RANGE = (-10.0, 10.0)
#: Cells batched into one bootstrap call (memory: rows x resamples x seeds floats).
_CHUNK = 64


def min_separable_seeds(alpha: float = ALPHA, comparisons: int = 1) -> int:
    """The fewest shared seeds with which :func:`leader_test` can separate a leader from
    ``comparisons`` others at ``alpha``: the smallest p, ``2 * 0.5 ** n`` (better on
    every seed), must reach Holm's first threshold ``alpha / comparisons``."""
    return math.ceil(math.log(alpha / (2.0 * max(1, comparisons))) / math.log(0.5) - 1e-12)


#: 6 at :data:`ALPHA` = 0.05: two families need 6 paired seeds, each one better, before
#: anything can be separated (with 5 the smallest two-sided p is 0.0625).
MIN_SEPARABLE_SEEDS = min_separable_seeds()


# --------------------------------------------------------------------------- cells


def _bootstrap(
    data: Any, statistic: Callable[..., Any], method: str, n_resamples: Optional[int] = None
) -> tuple[np.ndarray, np.ndarray]:
    from scipy import stats

    n_resamples = N_RESAMPLES if n_resamples is None else n_resamples

    with warnings.catch_warnings():  # a degenerate row gives NaN, handled by the caller
        warnings.simplefilter("ignore")
        res = stats.bootstrap(
            data,
            statistic,
            n_resamples=n_resamples,
            method=method,
            confidence_level=CONFIDENCE,
            vectorized=True,
            axis=-1,
            rng=np.random.default_rng(BOOTSTRAP_SEED),
        )
    return (
        np.asarray(res.confidence_interval.low, dtype=float),
        np.asarray(res.confidence_interval.high, dtype=float),
    )


def mean_intervals(samples: Sequence[Sequence[float] | np.ndarray]) -> list[tuple[float, float]]:
    """The :data:`CELL_METHOD` bootstrap interval (:data:`CONFIDENCE`) of the mean of each
    sample (its values over seeds), as ``(low, high)``; ``(nan, nan)`` for fewer than two
    values or a non-finite one (a diverged rollout's ``inf``: no interval), ``(v, v)``
    when every value is ``v``.

    Samples of one length are bootstrapped together, each with the same resampled
    indices (:data:`BOOTSTRAP_SEED`), so a sample's interval does not depend on the others.
    """
    arrays = [np.asarray(s, dtype=float).ravel() for s in samples]
    out: list[tuple[float, float]] = [(math.nan, math.nan)] * len(arrays)
    by_length: dict[int, list[int]] = {}
    for i, arr in enumerate(arrays):
        if arr.size < 2 or not np.all(np.isfinite(arr)):
            continue
        if np.all(arr == arr[0]):
            out[i] = (float(arr[0]), float(arr[0]))
            continue
        by_length.setdefault(arr.size, []).append(i)
    for indices in by_length.values():
        for start in range(0, len(indices), _CHUNK):
            chunk = indices[start : start + _CHUNK]
            low, high = _bootstrap((np.stack([arrays[i] for i in chunk]),), np.mean, CELL_METHOD)
            for i, lo, hi in zip(chunk, np.atleast_1d(low), np.atleast_1d(high), strict=True):
                if not (math.isfinite(lo) and math.isfinite(hi)):  # BCa degenerate: percentile
                    (lo,), (hi,) = _bootstrap((arrays[i][None, :],), np.mean, "percentile")
                out[i] = (float(lo), float(hi))
    return out


# --------------------------------------------------------------------------- paired test


def sign_test(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, better: str = "lower"
) -> tuple[float, int, int]:
    """One-sided exact sign test that ``a`` is better than ``b`` over paired seeds
    (``a[k]``, ``b[k]``: the same seed). A seed counts for ``a`` only where ``a[k]`` is a
    number strictly better than ``b[k]`` (``b[k]`` NaN: no result, which ``a`` beats); a
    tie, or ``a[k]`` NaN, counts against ``a``. Returns ``(p, wins, n)``:
    ``p = P(Binomial(n, 1/2) >= wins)``; ``p = 1`` without shared seeds."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.shape != y.shape:
        raise ValueError(f"sign_test: paired values need one shape, got {x.shape} and {y.shape}")
    n = int(x.size)
    if n == 0:
        return 1.0, 0, 0
    with np.errstate(invalid="ignore"):
        strictly = x > y if better == "higher" else x < y
    wins = int(np.sum(~np.isnan(x) & (strictly | np.isnan(y))))
    p = float(sum(math.comb(n, k) for k in range(wins, n + 1)) / 2.0**n)
    return p, wins, n


def leader_test(
    leader: Sequence[float] | np.ndarray,
    others: Sequence[Sequence[float] | np.ndarray],
    better: str = "lower",
    alpha: float = ALPHA,
) -> tuple[list[float], list[bool]]:
    """The leader against each of ``others`` (values paired seed by seed with
    ``leader``'s: ``others[j][k]`` and ``leader[k]`` share a seed; NaN where a run has
    no value): a two-sided exact sign test each (:func:`sign_test`'s counting, its p
    doubled), the p-values adjusted by Holm's step-down. Returns ``(adjusted p,
    separated)`` per other, in order: ``separated[j]`` where Holm rejects "the leader
    and other ``j`` are alike" at ``alpha``. The leader is best when every one is."""
    return paired_leader_test([(leader, other) for other in others], better, alpha)


def paired_leader_test(
    pairs: Sequence[tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]],
    better: str = "lower",
    alpha: float = ALPHA,
) -> tuple[list[float], list[bool]]:
    """:func:`leader_test` where each comparison has its own paired seeds: ``pairs[j]``
    is ``(the leader's values, other j's values)`` on the seeds the two share."""
    raw = []
    for mine, theirs in pairs:
        p, _, n = sign_test(np.asarray(mine, dtype=float), np.asarray(theirs, dtype=float), better)
        raw.append(min(1.0, 2.0 * p) if n else 1.0)
    return holm(raw, alpha)


def holm(p_values: Sequence[float], alpha: float = ALPHA) -> tuple[list[float], list[bool]]:
    """Holm's step-down adjustment of ``p_values``: ``(adjusted, rejected at alpha)``, in
    the given order (the family-wise error rate of the rejections is at most ``alpha``)."""
    m = len(p_values)
    order = sorted(range(m), key=lambda j: p_values[j])
    adjusted = [1.0] * m
    running = 0.0
    for rank, j in enumerate(order):
        running = max(running, min(1.0, (m - rank) * float(p_values[j])))
        adjusted[j] = running
    return adjusted, [a <= alpha for a in adjusted]


def paired_effect(
    leader: Sequence[float] | np.ndarray,
    other: Sequence[float] | np.ndarray,
    better: str = "lower",
    scale: str = "log",
) -> tuple[float, float, float, float]:
    """How much better the leader is than ``other``, seed by seed (paired): on a log
    scale ``log10(other / leader)`` for a lower-is-better metric (``log10(leader /
    other)`` for higher), on a linear scale the difference in the leader's favour;
    positive favours the leader. A seed where only the other has no finite value (a
    diverged run's ``inf``, a failed run's NaN) is ``+inf``, where only the leader has
    none ``-inf``, where neither has one 0. Returns ``(median, low, high, coverage)``:
    the median over seeds and the order-statistic interval ``[x_(k), x_(n+1-k)]`` with
    the largest ``k`` whose coverage ``1 - 2 P(Binomial(n, 1/2) < k)`` is at least
    :data:`CONFIDENCE` (the whole range, and its coverage, below 6 seeds)."""
    x = np.asarray(leader, dtype=float)
    y = np.asarray(other, dtype=float)
    if x.shape != y.shape or not x.size:
        return math.nan, math.nan, math.nan, math.nan
    sign = 1.0 if better == "lower" else -1.0
    effects = np.empty(x.size)
    tiny = np.finfo(float).tiny  # a log-scale value of 0 (exact) counts as the smallest
    for i, (a, b) in enumerate(zip(x, y, strict=True)):
        good_a, good_b = math.isfinite(a), math.isfinite(b)
        if good_a and good_b:
            effects[i] = sign * (
                math.log10(max(b, tiny)) - math.log10(max(a, tiny)) if scale == "log" else b - a
            )
        else:  # a side without a usable value loses the seed outright
            effects[i] = math.inf if good_a else (-math.inf if good_b else 0.0)
    values = np.sort(effects)
    n = values.size
    k = 1
    for candidate in range(1, n // 2 + 1):
        tail = sum(math.comb(n, j) for j in range(candidate)) / 2.0**n
        if 1.0 - 2.0 * tail >= CONFIDENCE:
            k = candidate
        else:
            break
    coverage = 1.0 - 2.0 * sum(math.comb(n, j) for j in range(k)) / 2.0**n
    return float(np.median(values)), float(values[k - 1]), float(values[n - k]), coverage


# --------------------------------------------------------------------------- aggregate


def iqm(values: Any, axis: Optional[int] = None) -> Any:
    """The interquartile mean: the mean of the middle half (:data:`IQM_CUT` cut from
    each end; ``scipy.stats.trim_mean``)."""
    from scipy import stats

    return stats.trim_mean(values, IQM_CUT, axis=axis)


def normalisation_scale(base: float, floor: float, rule: CheckRule) -> Optional[float]:
    """``log W(floor, base)``, the log of how many times worse the baseline ``base`` is
    than the ``floor`` (:meth:`CheckRule.worsening`: the rule's direction, values below its
    noise floor counting as it), or ``None`` where that is no scale: not finite, or
    within the metric's declared tolerance (``rule.factor``), so that the baseline is
    not measurably worse than the floor."""
    if not (math.isfinite(base) and math.isfinite(floor)):
        return None
    worse = rule.worsening(floor, base)
    if not (math.isfinite(worse) and worse > max(rule.factor, 1.0)):
        return None
    return math.log(worse)


def normalised_scores(
    values: Any, base: float, floor: float, rule: CheckRule
) -> Optional[np.ndarray]:
    """Each value's normalised score: ``1 - log W(floor, v) / log W(floor, base)``: 1 at
    the floor, 0 at the baseline, negative where worse than the baseline (``W``:
    :meth:`CheckRule.worsening`), clipped to :data:`SCORE_RANGE`; a NaN or infinite
    value (no result, or a diverged rollout) scores the range's lower end. ``None``
    where :func:`normalisation_scale` finds no scale."""
    scale = normalisation_scale(base, floor, rule)
    if scale is None:
        return None
    arr = np.asarray(values, dtype=float)
    out = np.full(arr.shape, SCORE_RANGE[0])
    for idx, v in np.ndenumerate(arr):
        if math.isfinite(v):
            worse = rule.worsening(floor, float(v))
            if worse > 0 and math.isfinite(worse):
                out[idx] = 1.0 - math.log(worse) / scale
    return np.clip(out, *SCORE_RANGE)


def _bootstrap_strata(
    arrays: Sequence[np.ndarray], statistic: Callable[..., Any], n_resamples: Optional[int] = None
) -> tuple[np.ndarray, np.ndarray]:
    """:data:`AGGREGATE_METHOD` interval of ``statistic(*arrays, axis=-1)``, each array
    resampled independently; an array of one value (nothing to resample: scipy needs
    two) stays as it is in every resample."""
    varying = [i for i, a in enumerate(arrays) if a.size >= 2]

    def wrapped(*samples: np.ndarray, axis: int = -1) -> Any:
        batch = samples[0].shape[:-1]
        given = iter(samples)
        full = [
            next(given) if i in varying else np.broadcast_to(a, (*batch, a.size))
            for i, a in enumerate(arrays)
        ]
        return statistic(*full, axis=axis)

    return _bootstrap(tuple(arrays[i] for i in varying), wrapped, AGGREGATE_METHOD, n_resamples)


def _pooled_iqm(*strata: np.ndarray, axis: int = -1) -> np.ndarray:
    """The IQM of every run of every stratum pooled (``(..., n_i)`` each)."""
    return iqm(np.concatenate(strata, axis=axis), axis=axis)


def stratified_interval(
    strata: Sequence[Sequence[float] | np.ndarray],
    statistic: Callable[..., Any] = _pooled_iqm,
) -> tuple[float, float, float]:
    """``(point, low, high)`` of ``statistic(*strata, axis=-1)`` (default: the IQM of
    every run pooled), the interval a :data:`AGGREGATE_METHOD` bootstrap (:data:`CONFIDENCE`)
    that resamples each stratum (a system's seeds) independently and keeps every stratum:
    the stratified bootstrap of Agarwal et al. (2021). A stratum of one run is kept as it
    is; with every stratum of one run the interval is ``(point, point)``."""
    arrays = [np.asarray(s, dtype=float).ravel() for s in strata if np.size(s)]
    if not arrays:
        return math.nan, math.nan, math.nan
    point = float(statistic(*[a[None, :] for a in arrays], axis=-1)[0])
    if all(a.size < 2 for a in arrays):
        return point, point, point
    low, high = _bootstrap_strata(arrays, statistic)
    return point, float(low), float(high)


def _improvement(*strata: np.ndarray, axis: int = -1) -> np.ndarray:
    """``P(X > Y)`` averaged over strata; ``strata`` = ``x_1, y_1, x_2, y_2, ...``."""
    probs = []
    for x, y in zip(strata[0::2], strata[1::2], strict=True):
        diff = x[..., :, None] - y[..., None, :]
        probs.append(np.mean((diff > 0) + 0.5 * (diff == 0), axis=(-2, -1)))
    return np.mean(np.stack(probs, axis=0), axis=0)


def probability_of_improvement(
    x: Sequence[np.ndarray], y: Sequence[np.ndarray]
) -> tuple[float, float, float]:
    """``(point, low, high)``: the probability that a run of X scores higher than a run
    of Y on the same system (Mann-Whitney: a tie counts one half), averaged over the
    systems both ran (``x[i]``, ``y[i]``: scores of system ``i``), with the stratified
    bootstrap interval (:func:`stratified_interval`: each system's runs of each
    competitor resampled independently)."""
    strata: list[np.ndarray] = []
    for xs, ys in zip(x, y, strict=True):
        xs, ys = np.asarray(xs, dtype=float).ravel(), np.asarray(ys, dtype=float).ravel()
        if xs.size and ys.size:
            strata += [xs, ys]
    if not strata:
        return math.nan, math.nan, math.nan
    return stratified_interval(strata, _improvement)


def performance_profile(
    strata: Sequence[np.ndarray], taus: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(fraction, low, high)`` over ``taus``: the share of runs whose score exceeds
    each ``tau``, each system weighted equally (the mean over systems of its share of
    seeds), with the stratified bootstrap interval of each point (Agarwal et al. 2021,
    "performance profiles")."""
    taus = np.asarray(taus, dtype=float)
    arrays = [np.asarray(s, dtype=float).ravel() for s in strata if np.size(s)]

    def profile(*runs: np.ndarray, axis: int = -1) -> np.ndarray:
        shares = [np.mean(r[..., None, :] > taus[:, None], axis=-1) for r in runs]
        # (..., resamples, taus) -> (taus, ..., resamples): scipy reads the last axis
        return np.moveaxis(np.mean(np.stack(shares, axis=0), axis=0), -1, 0)

    if not arrays:
        nan = np.full(taus.shape, math.nan)
        return nan, nan, nan
    point = profile(*[a[None, :] for a in arrays])[:, 0]
    if all(a.size < 2 for a in arrays):
        return point, point, point
    low, high = _bootstrap_strata(arrays, profile, n_resamples=2000)
    return point, low, high


# --------------------------------------------------------------------------- in words


def cell_rule() -> str:
    """What a cell's interval is (Markdown, one sentence part)."""
    return (
        f"mean over seeds [{CONFIDENCE:.0%} {CELL_METHOD} bootstrap interval of the mean "
        f"over seeds, `scipy.stats.bootstrap`, {N_RESAMPLES} resamples; none for one "
        "seed or an `inf`]"
    )


def best_rule() -> str:
    """When a cell is marked best or tied (Markdown, one sentence)."""
    return (
        f"**Bold**: best, separated from every other family with a value by "
        f"two-sided exact sign tests over their shared seeds, Holm-adjusted, at "
        f"{ALPHA:g} (a tie or a missing value counts against it; with n shared seeds "
        f"p >= 2 x 0.5^n, so it takes at least {MIN_SEPARABLE_SEEDS} seeds, each one "
        f"better, between two families and {min_separable_seeds(comparisons=5)} among six; "
        "the false-best rate of this rule, leader's choice included, is "
        "simulated in docs/STATISTICS.md); *italics*: tied for best, i.e. the leader "
        "(the best mean among the families whose every seed is `ok`) and every family "
        "it is not separated from (tied means not separated, not equivalent); `×r` or "
        "`+d` beside a leader: its median paired effect over the runner-up."
    )


def rank_rule() -> str:
    """How the headline across systems is made (Markdown, a few sentences)."""
    return (
        "Headline, free of any normalisation: each family's mean rank among the "
        "families (1 = best; a run without a finite value last; ties share the mean "
        "rank) on each system and seed, averaged over the seeds and then over the "
        f"systems every family ran, with a {CONFIDENCE:.0%} interval from a stratified "
        "bootstrap (seeds resampled within each system). P(A > B) below: the "
        "probability that a run of A is better than a run of B on the same system, "
        "from the metric's own values, averaged over the systems both ran; a claim "
        f"needs at least {MIN_SEPARABLE_SEEDS} seeds of each on every such system and "
        "an interval above 0.5."
    )


def aggregate_rule(baseline: str = "the baseline") -> str:
    """How the aggregate across systems is made (Markdown, a few sentences)."""
    return (
        f"Per system and metric, each run scores 1 - log W(floor, v) / log W(floor, "
        f"{baseline}), where W is how many times worse than the floor (the oracle, or "
        f"the metric's noise floor where no oracle ran, never below it) a value is: "
        f"0 at {baseline}'s mean, 1 at the floor, below 0 worse than {baseline}; a "
        f"diverged or failed run scores {SCORE_RANGE[0]:g}. Per family: the "
        f"interquartile mean (IQM) of its runs over every system, with a "
        f"{CONFIDENCE:.0%} {AGGREGATE_METHOD} interval from a stratified bootstrap "
        f"(seeds resampled within each system; `scipy.stats.bootstrap`, "
        f"{N_RESAMPLES} resamples; Agarwal et al. 2021)."
    )
