"""One competitor per family: family rows (the primary twin's), twin agreement, and the
best and tied marks (docs/STATISTICS.md, "One competitor per family", "Best and tied").
Nothing here names a family, model or backend: they come from the records.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np
import pandas as pd

from hnnbench import _registry as registry
from hnnbench._contracts.metric import CheckRule
from hnnbench._contracts.names import DEFAULT_TRACK, FAMILY_KEY, STANDING_STILL
from hnnbench._results import stats
from hnnbench._results.leaderboard import (
    board_metrics,
    flag_column,
    in_sample,
    leaderboard_frame,
    metric_declarations,
    text_column,
    variant_sort_key,
)

__all__ = [
    "EFFECT_SUFFIXES",
    "simulate_marks",
    "MARKS",
    "TOO_FEW",
    "UNBEATEN",
    "RANKING_KEY",
    "ROW_KEY",
    "SCOPE_KEY",
    "scope_name",
    "Families",
    "competitor",
    "families",
    "family_order",
    "key_of",
    "mark_best",
    "primary_rows",
    "references_in_every_track",
    "select",
    "twin_agreement",
]

#: A cell's mark: separated from every other family, or not separated from the leader;
#: on the standing-still reference's row, that no family's leader beats it on a metric
#: that requires it (:attr:`hnnbench.Metric.beat_reference`).
#: On the leader's row, where its shared seeds are too few for the leader test to
#: separate anything whatever they show: "too few seeds to separate".
MARKS = ("best", "tied", "unbeaten", "too_few_seeds")
UNBEATEN, TOO_FEW = MARKS[2], MARKS[3]
#: The leader's paired effect over the runner-up (:func:`hnnbench._results.stats.paired_effect`):
#: ``<metric>_effect`` (median over shared seeds), its interval, and
#: ``<metric>_effect_vs`` (the runner-up family).
EFFECT_SUFFIXES = ("_effect", "_effect_low", "_effect_high")
#: The keys, all from :data:`~hnnbench._contracts.names.FAMILY_KEY` (so that a field added
#: there, e.g. a track, separates every ranking and aggregate): a family row; one
#: ranking of families (one system); one aggregate across systems.
#: The track (docs/TUNING.md) is part of each: tracks are never ranked or aggregated
#: together (a frame without the column is of the protocol track).
ROW_KEY = (*FAMILY_KEY, "variant", "track")
RANKING_KEY = tuple(k for k in ROW_KEY if k != "family")
SCOPE_KEY = (*(k for k in FAMILY_KEY if k not in ("system", "family")), "track")


def scope_name(names: Sequence[str]) -> str:
    """``paper``, ``paper/tuned``: a scope's :data:`SCOPE_KEY` values joined, the
    protocol track (the default) left out."""
    return "/".join(
        str(n)
        for k, n in zip(SCOPE_KEY, names, strict=True)
        if not (k == "track" and n in ("", DEFAULT_TRACK))
    )


def _with_track(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with a ``track`` column (:data:`DEFAULT_TRACK` where it has none)."""
    return frame.assign(track=text_column(frame, "track", DEFAULT_TRACK))


def key_of(row: Any, keys: Sequence[str]) -> tuple[str, ...]:
    """``row``'s values of ``keys`` as strings (a missing or NaN variant is ``""``)."""
    out = []
    for k in keys:
        v = row.get(k, "") if hasattr(row, "get") else row[k]
        out.append("" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v))
    return tuple(out)


def select(frame: pd.DataFrame, keys: Sequence[str], values: Sequence[str]) -> pd.DataFrame:
    """The rows of ``frame`` whose ``keys`` hold ``values`` (compared as strings)."""
    mask = pd.Series(True, index=frame.index)
    for k, v in zip(keys, values, strict=True):
        mask &= text_column(frame, k) == v
    return frame[mask]


@dataclass
class Families:
    """The family view of a leaderboard.

    Attributes:
        board: one row per (:data:`~hnnbench._contracts.names.FAMILY_KEY`, variant): the
            primary twin's leaderboard row with ``family``, ``seeds_from`` (the primary
            model), ``models`` and ``backends`` (every twin, ``;``-joined), ``twins``
            (agreement, in words), ``twins_disagree`` (the metrics, and ``status``, the
            twins disagree on), and per ranked metric ``<metric>_mark``
            (:data:`MARKS` or ``""``) and ``<metric>_p`` (the sign test's p against the
            leader; the leader's: the largest against any other family).
        twins: :func:`twin_agreement`, one row per (family row, other twin).
        runs: the records-frame rows of every family's primary model (one per seed),
            with ``family`` set: the per-seed values the marks and the aggregate use.
        in_sample: the rows, as ``runs``, of tuned runs on their study's trial seeds
            (:func:`hnnbench._results.leaderboard.in_sample`): in no row, mark or
            aggregate; the tuning gain shows them apart (a family with no other tuned
            seed has no tuned row, so none are kept for it).
    """

    board: pd.DataFrame
    twins: pd.DataFrame = field(default_factory=pd.DataFrame)
    runs: pd.DataFrame = field(default_factory=pd.DataFrame)
    in_sample: pd.DataFrame = field(default_factory=pd.DataFrame)

    def metrics(self) -> list[str]:
        return board_metrics(self.board)


def competitor(frame: pd.DataFrame) -> pd.Series:
    """Each row's family: its ``family``, or its ``model`` where it has none."""
    family = frame["family"] if "family" in frame else pd.Series(None, index=frame.index)
    named = family.notna() & family.astype(str).str.strip().ne("")
    return family.where(named, frame["model"]).astype(str)


def _variant(frame: pd.DataFrame) -> pd.Series:
    return text_column(frame, "variant")


def _primary_key(row: Any) -> tuple[Any, ...]:
    n_ok = row.get("n_ok", 0)
    return (
        -int(row.get("n_seeds", 0) or 0),
        -int(0 if pd.isna(n_ok) else n_ok),
        str(row.get("backend") or ""),
        str(row["model"]),
    )


def references_in_every_track(frame: pd.DataFrame) -> pd.DataFrame:
    """The protocol track's reference runs (standing still, the oracle) that stand in
    another track of their (profile, system, variant) which did not run that reference:
    the reference's protocol runs on the seeds the track's models ran, with ``track``
    set (rows of a :func:`~hnnbench._results.leaderboard.records_frame`; empty if none).

    A track changes only the models' settings (the tuned track their search space, the
    recipe track their Config), never a system's data, so a reference (which has no
    settings) scores on a seed of that track what it scores on the protocol's; restricted
    to the track's seeds, its means are over the same seeds as the track's families."""
    frame = _with_track(frame)
    if frame.empty or "reference" not in frame:
        return frame[:0]
    is_ref = text_column(frame, "reference") != ""
    base = [k for k in ("profile", "system", "variant") if k in frame]
    added = []
    for _, group in frame.groupby(base, dropna=False, sort=False):
        refs = group[is_ref[group.index] & (group["track"] == DEFAULT_TRACK)]
        for track in sorted(set(group["track"].astype(str)) - {DEFAULT_TRACK}):
            mine = group[group["track"] == track]
            seeds = set(mine.loc[~is_ref[mine.index], "seed"])
            for model in sorted(set(refs["model"].astype(str)) - set(mine["model"].astype(str))):
                runs = refs[(refs["model"] == model) & refs["seed"].isin(seeds)]
                added.append(runs.assign(track=track))
    return pd.concat(added) if added else frame[:0]


def primary_rows(board: pd.DataFrame) -> pd.DataFrame:
    """The primary twin's row of every family of a leaderboard (or a reference CSV in its
    format), in the board's order, with ``family`` (:func:`competitor`), ``seeds_from``,
    ``models`` and ``backends`` (the family's twins in registry order) set."""
    if board.empty:
        return board.assign(seeds_from=[], models=[], backends=[])
    board = _with_track(board.copy())
    board["family"] = competitor(board)
    board["variant"] = _variant(board)
    rows = []
    for _, group in board.groupby(list(ROW_KEY), sort=False, dropna=False):
        records = [r for _, r in group.iterrows()]
        primary = min(records, key=_primary_key).copy()
        order = registry.ordered("model", [str(r["model"]) for r in records])
        by_model = {str(r["model"]): r for r in records}
        primary["seeds_from"] = str(primary["model"])
        primary["models"] = ";".join(order)
        primary["backends"] = ";".join(str(by_model[m].get("backend") or "") for m in order)
        rows.append(primary)
    return pd.DataFrame(rows).reset_index(drop=True)


def family_order(board: pd.DataFrame) -> list[str]:
    """The families of a family board in listing order: each at the registry position
    of its first model."""
    position: dict[str, int] = {}
    models = registry.ordered(
        "model", [m for ms in board["models"].astype(str) for m in ms.split(";") if m]
    )
    for family, ms in zip(board["family"].astype(str), board["models"].astype(str), strict=True):
        first = min((models.index(m) for m in ms.split(";") if m in models), default=10**6)
        position[family] = min(position.get(family, 10**6), first)
    return sorted(position, key=lambda f: (position[f], f))


# --------------------------------------------------------------------------- twins


def _rules() -> dict[str, CheckRule]:
    return {name: m.check for name, m in metric_declarations().items()}


def _fmt_factor(x: float) -> str:
    return "inf" if math.isinf(x) else f"{x:.3g}"


def _compare(
    a: pd.DataFrame, b: pd.DataFrame, metrics: Sequence[str], rules: dict[str, CheckRule]
) -> dict[str, Any]:
    """Twin ``b`` against ``a`` on their shared seeds: the largest factor apart per
    metric (``<metric>_apart``), whether they agree, and the disagreements in words."""
    shared = sorted(set(a["seed"].dropna().astype(int)) & set(b["seed"].dropna().astype(int)))
    out: dict[str, Any] = {"shared_seeds": ";".join(map(str, shared))}
    if not shared:
        out.update(agree=None, disagree="", difference="no shared seeds")
        return out
    a = a.assign(seed=a["seed"].astype(int)).set_index("seed").loc[shared]
    b = b.assign(seed=b["seed"].astype(int)).set_index("seed").loc[shared]
    problems: list[tuple[str, str]] = []
    for seed in shared:
        if a.at[seed, "status"] != b.at[seed, "status"]:
            problems.append(
                (
                    "status",
                    f"status at seed {seed}: {a.at[seed, 'status']} vs {b.at[seed, 'status']}",
                )
            )
            break
    for metric in metrics:
        rule = rules.get(metric, CheckRule())
        worst, where = math.nan, None
        for seed in shared:
            x = pd.to_numeric(a.at[seed, metric], errors="coerce") if metric in a else math.nan
            y = pd.to_numeric(b.at[seed, metric], errors="coerce") if metric in b else math.nan
            if pd.isna(x) and pd.isna(y):
                continue
            apart = (
                math.inf
                if (pd.isna(x) or pd.isna(y))
                else max(rule.worsening(float(x), float(y)), rule.worsening(float(y), float(x)))
            )
            if math.isnan(worst) or apart > worst:
                worst, where = apart, seed
        out[f"{metric}_apart"] = worst
        if not math.isnan(worst) and worst > rule.factor:
            problems.append(
                (
                    metric,
                    f"{metric} {_fmt_factor(worst)}x apart at seed {where} "
                    f"(tolerance {rule.factor:g}x)",
                )
            )
    out.update(
        agree=not problems,
        disagree=";".join(p[0] for p in problems),
        difference="; ".join(p[1] for p in problems),
    )
    return out


def twin_agreement(
    frame: pd.DataFrame, primaries: pd.DataFrame, metrics: Sequence[str]
) -> pd.DataFrame:
    """One row per (family row, other twin): ``profile``, ``system``, ``family``,
    ``variant``, ``model`` (the primary), ``twin``, ``shared_seeds``, ``agree`` (True,
    False, or None without a shared seed), ``disagree`` (the metrics, and ``status``,
    ``;``-joined), ``difference`` (in words) and ``<metric>_apart`` (the largest factor
    between the two on a shared seed, both directions, the metric's noise floor
    applied)."""
    rules = _rules()
    rows = []
    frame = frame.assign(family=competitor(frame), variant=_variant(frame))
    for _, fam in primaries.iterrows():
        models = [m for m in str(fam["models"]).split(";") if m]
        if len(models) < 2:
            continue
        mine = select(frame, RANKING_KEY, key_of(fam, RANKING_KEY))
        base = mine[mine["model"] == fam["seeds_from"]]
        for twin in models:
            if twin == fam["seeds_from"]:
                continue
            row = {
                **dict(zip(ROW_KEY, key_of(fam, ROW_KEY), strict=True)),
                "model": fam["seeds_from"],
                "twin": twin,
            }
            row.update(_compare(base, mine[mine["model"] == twin], metrics, rules))
            rows.append(row)
    columns = [
        *ROW_KEY,
        "model",
        "twin",
        "shared_seeds",
        "agree",
        "disagree",
        "difference",
        *(f"{m}_apart" for m in metrics),
    ]
    return pd.DataFrame(rows, columns=columns)


def _twin_summary(rows: pd.DataFrame) -> tuple[str, str]:
    """``(words, disagree)`` for one family row from its twin-agreement rows."""
    if rows.empty:
        return "", ""
    words, disagree = [], []
    for _, r in rows.iterrows():
        n = len([s for s in str(r["shared_seeds"]).split(";") if s])
        if r["agree"] is None or (isinstance(r["agree"], float) and math.isnan(r["agree"])):
            words.append(f"{r['twin']}: no shared seed")
        elif bool(r["agree"]):
            words.append(f"{r['twin']} agrees ({n} seed{'s' if n != 1 else ''})")
        else:
            words.append(f"{r['twin']} disagrees: {r['difference']}")
            disagree += [m for m in str(r["disagree"]).split(";") if m]
    return "; ".join(words), ";".join(dict.fromkeys(disagree))


# --------------------------------------------------------------------------- marks


def _in_domain(value: float, domain: tuple[float, float], worst: float) -> bool:
    if math.isnan(value):
        return False
    return value == worst or (math.isfinite(value) and domain[0] <= value <= domain[1])


def _per_seed(runs: pd.DataFrame, metric: str) -> dict[int, float]:
    if metric not in runs:
        return {int(s): math.nan for s in runs["seed"].dropna()}
    values = pd.to_numeric(runs[metric], errors="coerce")
    return {int(s): float(v) for s, v in zip(runs["seed"], values, strict=True) if not pd.isna(s)}


def _passes_guard(group: pd.DataFrame, i: Any, decl: Any) -> bool:
    """Whether row ``i`` may lead on a metric with :attr:`Metric.best_requires`
    ``(metric, threshold)``: its mean of that metric exceeds the threshold (e.g. a rollout
    that beats standing still, for an energy error the zero field would win). Records
    from before the guard metric existed (no finite value in the group) are not
    guarded."""
    if decl.best_requires is None:
        return True
    guard, threshold = decl.best_requires
    column = f"{guard}_mean"
    if column not in group:
        return True
    values = pd.to_numeric(group[column], errors="coerce")
    if not values.map(math.isfinite).any():
        return True
    value = float(values[i])
    return math.isfinite(value) and value > threshold


def mark_best(board: pd.DataFrame, runs: pd.DataFrame) -> pd.DataFrame:
    """``board`` (family rows) with ``<metric>_mark`` and ``<metric>_p`` for every ranked
    metric (see the module docstring); ``runs``: the primary models' records-frame rows,
    with ``family`` set. A mean outside the metric's declared domain (from a record a
    strict load refuses) takes no part."""
    declared = metric_declarations()
    metrics = [m for m in board_metrics(board) if m in declared and declared[m].ranked]
    board = _with_track(board).reset_index(drop=True)
    runs = _with_track(runs)
    for m in metrics:
        board[f"{m}_mark"] = ""
        board[f"{m}_p"] = math.nan
        for suffix in EFFECT_SUFFIXES:
            board[f"{m}{suffix}"] = math.nan
        board[f"{m}_effect_vs"] = ""
    if board.empty:
        return board
    ranked = flag_column(board, "ranked", True)
    full = (
        (board["n_ok"] == board["n_seeds"])
        if {"n_ok", "n_seeds"} <= set(board)
        else pd.Series(True, index=board.index)
    )
    runs = runs.assign(variant=_variant(runs))
    board["variant"] = _variant(board)
    still_rows = _standing_still(board)
    runs_of = _by_key(runs, RANKING_KEY)
    still_of = _by_key(still_rows, RANKING_KEY)
    for _, group in board[ranked].groupby(list(RANKING_KEY), dropna=False, sort=False):
        key = key_of(group.iloc[0], RANKING_KEY)
        mine = runs_of.get(key, runs[:0])
        still = still_of.get(key, still_rows[:0])
        for metric in metrics:
            decl = declared[metric]
            means = pd.to_numeric(group[f"{metric}_mean"], errors="coerce")
            cand = [
                i
                for i in group.index
                if _in_domain(float(means[i]), decl.domain, decl.worst())
                and _passes_guard(group, i, decl)
            ]
            eligible = [i for i in cand if full[i] and math.isfinite(float(means[i]))]
            if len(cand) < 2 or not eligible:
                continue
            sign = -1.0 if decl.better == "higher" else 1.0
            leader = min(eligible, key=lambda i: sign * float(means[i]))
            if decl.beat_reference:
                # Marked only where the leader beats standing still on this metric.
                if still.empty:
                    continue  # no reference row: nothing is claimed
                floor = (
                    float(pd.to_numeric(still[f"{metric}_mean"], errors="coerce").iloc[0])
                    if f"{metric}_mean" in still
                    else math.nan
                )
                if math.isfinite(floor) and not sign * float(means[leader]) < sign * floor:
                    board.at[still.index[0], f"{metric}_mark"] = UNBEATEN
                    continue
                if not math.isfinite(floor):
                    continue
            seeds = {
                i: _per_seed(mine[mine["family"] == board.at[i, "family"]], metric) for i in cand
            }
            others = [i for i in cand if i != leader]
            shared = {i: sorted(set(seeds[leader]) & set(seeds[i])) for i in others}
            fewest = min(len(v) for v in shared.values())
            if fewest < stats.min_separable_seeds(comparisons=len(others)):
                # no outcome of these seeds could separate anything: say so, claim nothing
                board.at[leader, f"{metric}_mark"] = TOO_FEW
                continue
            ps, separated = _holm(seeds, leader, others, shared, decl.better)
            board.at[leader, f"{metric}_mark"] = "best" if all(separated.values()) else "tied"
            board.at[leader, f"{metric}_p"] = max(ps.values())
            for i in others:
                board.at[i, f"{metric}_p"] = ps[i]
                if not separated[i]:
                    board.at[i, f"{metric}_mark"] = "tied"
            runner = min(
                others,
                key=lambda i: (
                    sign * float(means[i]) if math.isfinite(float(means[i])) else math.inf
                ),
            )
            effect = stats.paired_effect(
                [seeds[leader][s] for s in shared[runner]],
                [seeds[runner][s] for s in shared[runner]],
                decl.better,
                decl.scale,
            )
            (
                board.at[leader, f"{metric}_effect"],
                board.at[leader, f"{metric}_effect_low"],
                board.at[leader, f"{metric}_effect_high"],
            ) = effect[:3]
            board.at[leader, f"{metric}_effect_vs"] = str(board.at[runner, "family"])
    return board


def _holm(
    seeds: dict[Any, dict[int, float]],
    leader: Any,
    others: list[Any],
    shared: dict[Any, list[int]],
    better: str,
) -> tuple[dict[Any, float], dict[Any, bool]]:
    """:func:`hnnbench._results.stats.leader_test` of the leader against ``others``, each on the
    seeds it shares with the leader: ``({other: Holm-adjusted p}, {other: separated})``."""
    pairs = [
        ([seeds[leader][s] for s in shared[i]], [seeds[i][s] for s in shared[i]]) for i in others
    ]
    adjusted, separated = stats.paired_leader_test(pairs, better)
    return dict(zip(others, adjusted, strict=True)), dict(zip(others, separated, strict=True))


def simulate_marks(
    families: int, seeds: int, draws: int, metric: str, effect: float = 0.0, seed: int = 0
) -> dict[str, float]:
    """How :func:`mark_best` marks ``draws`` simulated cells of ``families`` families over
    ``seeds`` paired seeds (docs/STATISTICS.md, "The leader test, simulated").

    Every family's value at seed ``s`` is ``exp(u_s + e)``, with ``u_s ~ N(0, 1)`` shared
    by the families at that seed (seeds pair) and ``e ~ N(0, 1)`` its own; the first
    family's ``e`` is shifted by ``effect`` in its favour (``effect = 0``: identical
    families). Returns the share of draws with a ``best`` mark (``"any_best"``: under
    ``effect = 0`` the false-best rate), with the first family best (``"power"``), and
    with ``too_few_seeds`` (``"too_few"``)."""
    declared = metric_declarations()[metric]
    sign = 1.0 if declared.better == "lower" else -1.0
    rng = np.random.default_rng(seed)
    rows, runs = [], []
    names = [f"f{j}" for j in range(families)]
    for d in range(draws):
        shared = rng.normal(size=seeds)
        for j, name in enumerate(names):
            own = rng.normal(size=seeds) - (sign * effect if j == 0 else 0.0)
            values = np.exp(shared + own)
            rows.append(
                {
                    "profile": "sim",
                    "system": f"d{d}",
                    "family": name,
                    "variant": "",
                    "ranked": True,
                    "n_seeds": seeds,
                    "n_ok": seeds,
                    f"{metric}_mean": float(np.mean(values)),
                }
            )
            runs += [
                {
                    "profile": "sim",
                    "system": f"d{d}",
                    "family": name,
                    "variant": "",
                    "seed": k,
                    "status": "ok",
                    metric: float(v),
                }
                for k, v in enumerate(values)
            ]
    board = mark_best(pd.DataFrame(rows), pd.DataFrame(runs))
    marks = board[f"{metric}_mark"].astype(str)
    best = board[marks == "best"]
    return {
        "any_best": len(best) / draws,
        "power": float((best["family"] == names[0]).sum()) / draws,
        "too_few": float((marks == TOO_FEW).sum()) / draws,
    }


def _by_key(frame: pd.DataFrame, keys: Sequence[str]) -> dict[tuple[str, ...], pd.DataFrame]:
    """``frame``'s rows grouped by their :func:`key_of` ``keys`` (one pass, not a filter
    per group)."""
    if frame.empty:
        return {}
    labels = pd.Series([key_of(r, keys) for r in frame.to_dict("records")], index=frame.index)
    return {k: frame.loc[idx] for k, idx in labels.groupby(labels).groups.items()}


def _standing_still(board: pd.DataFrame) -> pd.DataFrame:
    """The rows of ``board`` that are the standing-still reference
    (:data:`~hnnbench._contracts.names.STANDING_STILL`)."""
    return board[text_column(board, "reference") == STANDING_STILL]


# --------------------------------------------------------------------------- the view


def families(frame: pd.DataFrame, board: Optional[pd.DataFrame] = None) -> Families:
    """The family view (:class:`Families`) of a records frame
    (:func:`hnnbench._results.leaderboard.records_frame`; ``board``: its leaderboard, when already
    built). Rows are ordered by profile, system (registry order), family
    (:func:`family_order`) and variant."""
    if board is None:
        board = leaderboard_frame(frame)
    board, frame = _with_track(board), _with_track(frame)
    held_out = in_sample(frame)
    sample, frame = frame[held_out], frame[~held_out]
    if board.empty:
        return Families(board.assign(family=[], seeds_from=[], models=[], backends=[]))
    standing_in = references_in_every_track(frame)
    if not standing_in.empty:
        board = pd.concat([board, _with_track(leaderboard_frame(standing_in))], ignore_index=True)
        frame = pd.concat([frame, standing_in], ignore_index=True)
    primaries = primary_rows(board)
    metrics = board_metrics(board)
    frame = frame.assign(family=competitor(frame), variant=_variant(frame))
    twins = twin_agreement(frame, primaries, metrics)
    words, disagree = [], []
    for _, fam in primaries.iterrows():
        w, d = _twin_summary(select(twins, ROW_KEY, key_of(fam, ROW_KEY)))
        words.append(w)
        disagree.append(d)
    primaries["twins"], primaries["twins_disagree"] = words, disagree
    keep = {(*key_of(r, RANKING_KEY), str(r["seeds_from"])) for _, r in primaries.iterrows()}

    def primary(rows: pd.DataFrame) -> pd.DataFrame:
        return rows[
            [(*key_of(r, RANKING_KEY), str(r["model"])) in keep for _, r in rows.iterrows()]
        ]

    runs = primary(frame)
    sample = primary(sample.assign(family=competitor(sample), variant=_variant(sample)))
    board_out = mark_best(primaries, runs)
    order = family_order(board_out)
    systems = registry.ordered("system", board_out["system"].astype(str))

    def key(i: int) -> tuple[Any, ...]:
        r = board_out.iloc[i]
        return (
            key_of(r, SCOPE_KEY),
            systems.index(str(r["system"])),
            order.index(str(r["family"])),
            variant_sort_key(r["variant"]),
        )

    board_out = board_out.iloc[sorted(range(len(board_out)), key=key)].reset_index(drop=True)
    head = [c for c in (*ROW_KEY, "seeds_from", "models", "backends") if c in board_out]
    rest = [c for c in board_out.columns if c not in head and c not in ("model", "backend")]
    if not _variant(board_out).ne("").any():
        head.remove("variant")
        rest = [c for c in rest if c != "variant"]
    return Families(
        board_out[head + rest], twins, runs.reset_index(drop=True), sample.reset_index(drop=True)
    )
