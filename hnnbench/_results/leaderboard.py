"""Flatten run records into pandas tables: one row per record, per seed, or per
(profile, system, model, variant, track) for the leaderboard.

Systems, models and metrics are ordered as the registry orders them
(:func:`hnnbench._registry.groups.ordered`); what a metric is (direction, scale) comes from its
declaration (:class:`hnnbench._contracts.metric.Metric`). Nothing here names a plugin.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from hnnbench import _registry as registry
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._contracts.metric import Metric
from hnnbench._contracts.names import (
    BOARD_KEY,
    DEFAULT_TRACK,
    FRAME_COLUMNS,
    ID_COLUMNS,
    JOB_FIELDS,
    PROVENANCE_COLUMNS,
    RESERVED,
    STATUS_COLUMNS,
    STATUSES,
    TIMINGS,
    TRACKS,
)
from hnnbench._record.tracks import TRACK_KEYS, on_trial_seed, track_of, tuned_settings
from hnnbench._results import stats
from hnnbench._results.provenance import reserved_key_problem
from hnnbench._running.config import RUN_ONLY_KEYS

__all__ = [
    "INTERVAL_SUFFIXES",
    "direction_header",
    "display_frame",
    "variant_overrides",
    "summary_metrics",
    "format_interval",
    "format_value",
    "in_sample",
    "leaderboard",
    "leaderboard_frame",
    "records_frame",
    "summary_frame",
    "variant_labels",
]


def summary_metrics() -> list[str]:
    """The metrics shown in the end-of-sweep summary table, in table order."""
    return [m.name for m in registry.metrics() if m.summary]


def metric_declarations() -> dict[str, Metric]:
    """``{name: Metric}`` of the registered metrics."""
    return {m.name: m for m in registry.metrics()}


#: The mark a column header carries for the direction of its metric.
DIRECTION_MARKS = {"lower": "\u2193", "higher": "\u2191"}
#: Header suffixes of columns derived from a metric, and which way they read: a mean
#: rank (1 = best) and an IQM of normalised scores (1 = the floor, 0 = the baseline).
DERIVED_DIRECTIONS = {" rank": "lower", " IQM": "higher"}


def direction_header(column: str, declared: dict[str, Metric] | None = None) -> str:
    """A table's column header with the direction of its metric (from the metric's
    declaration, :attr:`Metric.better`): ``energy_mse ↓`` (lower is better),
    ``rollout_skill ↑``, ``energy_mse rank ↓``, ``energy_mse IQM ↑``; any other
    column, or one already marked, as it is."""
    text = str(column)
    if text.endswith(tuple(DIRECTION_MARKS.values())):
        return text
    declared = metric_declarations() if declared is None else declared
    if text in declared:
        return f"{text} {DIRECTION_MARKS[declared[text].better]}"
    for suffix, better in DERIVED_DIRECTIONS.items():
        if text.endswith(suffix) and text[: -len(suffix)] in declared:
            return f"{text} {DIRECTION_MARKS[better]}"
    return text


#: Override keys that do not define a variant: the identity columns, and settings that
#: say where and how a job runs rather than what it computes.
NON_VARIANT_KEYS = frozenset(JOB_FIELDS) | RUN_ONLY_KEYS | frozenset(TRACK_KEYS)


def variant_overrides(record: dict[str, Any]) -> list[str]:
    """The record's overrides that may define its variant: a tuned record's selected
    settings are its track's definition (``tuning.selected``), not a variant."""
    tuned = tuned_settings(record)
    return [
        o
        for o in record.get("overrides") or ()
        if str(o).lstrip("+~").split("=", 1)[0] not in tuned
    ]


def _variant_items(overrides: Iterable[str] | None) -> dict[str, str]:
    """``key -> "key=value"`` of the overrides that may define a variant (Hydra's
    append prefix ``+``/``++`` dropped, so ``+a=1`` and ``a=1`` are one variant)."""
    items = {}
    for text in overrides or ():
        text = str(text).lstrip("+")
        key = text.split("=", 1)[0].lstrip("~")
        if key not in NON_VARIANT_KEYS and not key.startswith("hydra"):
            items[key] = text
    return items


def variant_sort_key(variant: str) -> tuple[tuple[str, int, float, str], ...]:
    """Orders variants by key, then by numeric value where the values are numbers
    (``model.hidden=200`` before ``model.hidden=1000``)."""
    out = []
    for token in str(variant).split():
        key, _, value = token.partition("=")
        try:
            out.append((key, 0, float(value), ""))
        except ValueError:
            out.append((key, 1, 0.0, value))
    return tuple(out)


def variant_labels(overrides: Sequence[Iterable[str] | None]) -> list[str]:
    """The configuration variant of each of a set of runs, from their command-line
    overrides: the overrides whose value is not the same for every run (an override all
    runs share is a setting of the whole sweep, shown in its command, not a variant),
    leaving out system, model, seed, profile and the run settings of
    :data:`NON_VARIANT_KEYS`; sorted and space-separated, ``""`` where there is none.

    ``hnnbench -m system=spring model=hnn_torch model.hidden=100,200`` gives
    ``"model.hidden=100"`` and ``"model.hidden=200"``: runs of one (system, model) that
    differ in it are different rows of every table, never seeds of one row.
    """
    items = [_variant_items(o) for o in overrides]
    keys = set().union(*items) if items else set()
    varying = {k for k in keys if len({it.get(k) for it in items}) > 1}
    return [" ".join(sorted(v for k, v in it.items() if k in varying)) for it in items]


def text_column(frame: pd.DataFrame, name: str, default: str = "") -> pd.Series:
    """Column ``name`` of ``frame`` as strings, ``default`` where a value is missing (NaN,
    None) and in every row when ``frame`` has no such column (e.g. ``variant``,
    ``reference``, ``track``: records of older schemas, boards without variants)."""
    if name not in frame:
        return pd.Series(default, index=frame.index, dtype=object)
    return frame[name].fillna(default).astype(str)


def flag_column(frame: pd.DataFrame, name: str, default: bool) -> pd.Series:
    """Column ``name`` of ``frame`` as booleans, ``default`` where a value is missing and
    in every row when ``frame`` has no such column (e.g. ``ranked``: true unless declared)."""
    if name not in frame:
        return pd.Series(default, index=frame.index, dtype=bool)
    column = frame[name].astype(object)
    return column.where(column.notna(), default).astype(bool)


def in_sample(frame: pd.DataFrame) -> pd.Series:
    """Whether each run of a records frame is a tuned run on one of its study's trial
    seeds (``tuning_trial_seed``): the selected trial run again, chosen for its score on
    that very seed. The tuned track's rows, and so its tests and verdicts, leave these
    runs out and read the final seeds no trial trained; the tuning gain shows them
    apart (docs/TUNING.md, "Which seeds a tuned row reads"). A failed, timed-out or
    skipped run on a trial seed is not left out: it carries no value, and its row
    still counts it."""
    valued = text_column(frame, "status").isin(("ok", "diverged"))
    return flag_column(frame, "tuning_trial_seed", False) & valued


def _has_variants(frame: pd.DataFrame) -> bool:
    return bool((text_column(frame, "variant") != "").any())


def _has_tracks(frame: pd.DataFrame) -> bool:
    """Whether some run is of another track than the protocol (the leaderboard then
    shows a ``track`` column and the tuning's CPU seconds)."""
    return bool((text_column(frame, "track", DEFAULT_TRACK) != DEFAULT_TRACK).any())


def records_frame(
    records: Iterable[dict[str, Any]], variants: Sequence[str] | None = None
) -> pd.DataFrame:
    """One row per record: the identity and status columns of
    :data:`hnnbench._contracts.names.FRAME_COLUMNS` (``variant``: ``variants``, one per record,
    e.g. derived from the records' configs by ``hnnbench check``; default: from their
    overrides, :func:`variant_labels`), ``<metric>`` means, ``<metric>_sem`` and
    ``<timing>`` columns.

    Raises:
        HnnbenchError: a record whose metric or timing key is named like another column
            (it would replace it; one line naming the file and the key).
    """
    records = list(records)
    if variants is None:
        variants = variant_labels([variant_overrides(rec) for rec in records])
    rows = []
    for rec, variant in zip(records, variants, strict=True):
        problem = reserved_key_problem(rec)
        if problem is not None:
            where = f"{rec['path']}/result.json" if rec.get("path") else "a record"
            raise HnnbenchError(f"{where}: {problem}; the record is refused")
        env = rec.get("environment") or {}
        tuning = rec.get("tuning")
        derived = {
            "variant": variant,
            "track": track_of(rec),
            "tuning_cpu_s": tuning.get("cpu_s") if isinstance(tuning, dict) else None,
            "tuning_study": tuning.get("study") if isinstance(tuning, dict) else None,
            "criterion_value": _selection_field(rec, "validation_loss"),
            "tuning_trial_seed": on_trial_seed(rec),
            "ranked": _ranked(rec),
            "reference": _reference(rec),
            "converged": _selection_field(rec, "converged"),
            "git_commit": env.get("git_commit"),
            "machine": env.get("host") or env.get("platform"),
            "trained": _selection_field(rec, "trained"),
        }
        row: dict[str, Any] = {
            name: derived[name] if name in derived else rec.get(name) for name in FRAME_COLUMNS
        }
        for name, value in (rec.get("metrics") or {}).items():
            row[name] = value.get("mean")
            row[f"{name}_sem"] = value.get("sem")
        for name, value in (rec.get("timings") or {}).items():
            row[name] = value
        rows.append(row)
    return pd.DataFrame(rows)


def _selection_field(rec: dict[str, Any], key: str) -> Any:
    """``selection.<key>`` of a record (``trained``: ``False`` for a run that did not
    train; ``converged``: whether its criterion stopped improving over the last 20% of
    steps), ``None`` where there is no selection or no such key."""
    selection = rec.get("selection")
    return selection.get(key) if isinstance(selection, dict) else None


def _reference(rec: dict[str, Any]) -> str:
    """The record's reference role (``""`` for a competitor); records before schema 3
    lack the field: the installed class says."""
    if "reference" in rec:
        return str(rec["reference"] or "")
    info = registry.discover("model").get(str(rec.get("model")))
    return str(getattr(info.cls, "reference", None) or "") if info is not None and info.ok else ""


def _ranked(rec: dict[str, Any]) -> bool:
    """Whether the record's model competes (records before schema 2 lack the field:
    the installed class says)."""
    if rec.get("ranked") is not None:
        return bool(rec["ranked"])
    info = registry.discover("model").get(str(rec.get("model")))
    return bool(getattr(info.cls, "ranked", True)) if info is not None and info.ok else True


def summary_frame(frame: pd.DataFrame, metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """One row per (system, model, variant, seed) with the status and every metric
    (``metrics``: a subset, e.g. :func:`summary_metrics` for a printed table); the
    ``variant`` column only when some run has one."""
    if frame.empty:
        return frame
    ids = [
        "system",
        "model",
        *(["variant"] if _has_variants(frame) else []),
        *(["track"] if _has_tracks(frame) else []),
        "seed",
    ]
    cols = [*ids, "status"]
    names = metric_names(frame) if metrics is None else list(metrics)
    cols += [m for m in names if m in frame.columns]
    cols += [c for c in (COST_COLUMN,) if c in frame.columns]
    out = frame[cols].reset_index(drop=True)
    if "error" in frame and (frame["status"] != "ok").any():
        out.insert(
            out.columns.get_loc("status") + 1,
            "reason",
            frame["error"].where(frame["status"] != "ok").reset_index(drop=True),
        )
    systems = registry.ordered("system", out["system"].astype(str))
    models = registry.ordered("model", out["model"].astype(str))

    def key(i: int) -> tuple[Any, ...]:  # leaderboard order, then variant, then seed
        r = out.iloc[i]
        seed = pd.to_numeric(r["seed"], errors="coerce")
        return (
            systems.index(str(r["system"])),
            models.index(str(r["model"])),
            variant_sort_key(r["variant"]) if "variant" in out else (),
            _track_rank(str(r["track"])) if "track" in out else (),
            math.inf if pd.isna(seed) else float(seed),
        )

    return out.iloc[sorted(range(len(out)), key=key)].reset_index(drop=True)


# --------------------------------------------------------------------------- leaderboard

#: The timing tables show: CPU seconds of the job's process (wall time, ``total_s``, is
#: in the CSV; on a shared machine it measures the crowd as much as the job).
COST_COLUMN = "cpu_s"
#: The interval columns of each metric: ``<metric>_ci_low``, ``<metric>_ci_high``
#: (:func:`hnnbench._results.stats.mean_intervals`).
INTERVAL_SUFFIXES = ("_ci_low", "_ci_high")


def linear_metrics() -> frozenset[str]:
    """Metrics shown on a linear scale (the others span decades: log scale)."""
    return frozenset(m.name for m in registry.metrics() if m.scale == "linear")


def metric_names(frame: pd.DataFrame) -> list[str]:
    """Metric names present in a records frame, in the registry's table order (metrics
    no installed plugin declares follow, by name)."""
    found = [
        c
        for c in frame.columns
        if c not in RESERVED and not c.endswith("_sem") and not c.endswith("_s")
    ]
    declared = [m.name for m in registry.metrics()]
    return [m for m in declared if m in found] + sorted(m for m in found if m not in declared)


def seed_values(values: pd.Series) -> np.ndarray:
    """The values of a metric over seeds, as floats, NaN (not applicable) left out."""
    arr = pd.to_numeric(values, errors="coerce").to_numpy(dtype=float)
    return arr[~np.isnan(arr)]


def tuning_cpu(group: pd.DataFrame) -> float:
    """The CPU seconds of the studies that chose a pair's tuned settings: each study's
    (every record of a study states it) summed over the pair's studies (one per fold on
    a measured system; records that name no study count as one). NaN where a study
    states none (a sum without it would undercount)."""
    if "tuning_cpu_s" not in group:
        return math.nan
    cpu = pd.to_numeric(group["tuning_cpu_s"], errors="coerce")
    per_study = cpu.groupby(text_column(group, "tuning_study")).max()
    return float(per_study.sum()) if per_study.notna().all() and len(per_study) else math.nan


def _agg(values: pd.Series) -> tuple[float, float]:
    """Mean and sample std over seeds; ``inf`` mean if any value is infinite (a
    diverged rollout), NaN values (metric not applicable) ignored."""
    arr = seed_values(values)
    if arr.size == 0:
        return math.nan, math.nan
    if np.any(np.isinf(arr)):
        return float(np.mean(arr)), math.nan
    std = float(np.std(arr, ddof=1)) if arr.size >= 2 else math.nan
    return float(np.mean(arr)), std


def reason_text(group: pd.DataFrame) -> str:
    """Why runs of one pair were not ``ok``: each status with its seeds and its
    records' ``error`` (``skipped (seeds 0, 1, 2): <why>``), ``; ``-joined; ``""`` when
    every run is ``ok``."""
    parts = []
    for status in STATUSES:
        if status == "ok":
            continue
        sel = group[group["status"] == status]
        if sel.empty:
            continue
        errors = sel["error"] if "error" in sel else pd.Series([None] * len(sel))
        by_error: dict[str, list[str]] = {}
        for seed, error in zip(sel["seed"], errors, strict=True):
            text = (
                " ".join(str(error).split())
                if error is not None and not pd.isna(error)
                else "no reason recorded"
            )
            by_error.setdefault(text, []).append("?" if pd.isna(seed) else str(int(seed)))
        for text, seeds in by_error.items():
            label = "seed" if len(seeds) == 1 else "seeds"
            parts.append(f"{status} ({label} {', '.join(seeds)}): {text}")
    return "; ".join(parts)


def status_text(counts: dict[str, int]) -> str:
    """``ok``, ``diverged`` or ``2 ok, 1 diverged``."""
    present = {s: n for s, n in counts.items() if n}
    if len(present) == 1:
        return next(iter(present))
    return ", ".join(f"{n} {s}" for s, n in present.items())


def leaderboard(
    records: Iterable[dict[str, Any]], variants: Sequence[str] | None = None
) -> pd.DataFrame:
    """The leaderboard of run records (see :func:`leaderboard_frame`; ``variants``:
    as :func:`records_frame`)."""
    return leaderboard_frame(records_frame(list(records), variants))


def _refuse_repeated_seeds(group: pd.DataFrame) -> None:
    """A seed held by two records of one (profile, system, model, variant) would be
    counted twice in the mean and the spread."""
    repeated = group[group["seed"].duplicated(keep=False) & group["seed"].notna()]
    if repeated.empty:
        return
    first = repeated.iloc[0]
    paths = (
        repeated.loc[repeated["seed"] == first["seed"], "path"]
        if "path" in repeated
        else pd.Series([])
    )
    where = " and ".join(str(p) for p in paths.dropna()) or "two records"
    raise HnnbenchError(
        f"{first['system']} x {first['model']} seed {first['seed']} ({first['profile']} "
        f"profile) is recorded twice ({where}): the leaderboard would count it twice; "
        "move one of them out of the directories given"
    )


def leaderboard_frame(frame: pd.DataFrame, metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """One row per (profile, system, model, variant, track) of a :func:`records_frame`.

    Columns: :data:`ID_COLUMNS` (with ``variant`` after ``model`` when some run has a
    variant, and ``track`` after it when some run is not of the protocol track, so a
    sweep of the protocol without variants keeps the plain schema; tracks are never
    ranked together), :data:`STATUS_COLUMNS`
    (``reason``: :func:`reason_text`), ``<metric>_mean``, ``<metric>_std`` and the
    interval ``<metric>_ci_low``, ``<metric>_ci_high`` (over seeds:
    :func:`hnnbench._results.stats.mean_intervals`, NaN for one seed or an infinite value) for
    every metric, ``<timing>_mean`` for :data:`TIMINGS`. A tuned run on one of its
    study's trial seeds is left out (:func:`in_sample`). Metrics are aggregated over the
    ``ok`` runs; a pair with no ``ok`` run is aggregated over its ``diverged`` runs, so
    it shows ``inf`` where its rollouts diverged (and its finite losses). Failed or
    skipped runs only: NaN, status and reason say why.
    """
    if metrics is None:
        metrics = metric_names(frame) if not frame.empty else []
    variants = _has_variants(frame)
    tracks = _has_tracks(frame)
    ids = list(ID_COLUMNS)
    if variants:
        ids.insert(ids.index("model") + 1, "variant")
    if tracks:
        ids.insert(ids.index("model") + 1 + variants, "track")
    columns = [*ids, *STATUS_COLUMNS]
    for m in metrics:
        columns += [f"{m}_mean", f"{m}_std", *(f"{m}{x}" for x in INTERVAL_SUFFIXES)]
    columns += [f"{t}_mean" for t in TIMINGS]
    if tracks:
        columns.append("tuning_cpu_s")
    columns += list(PROVENANCE_COLUMNS)
    if frame.empty:
        return pd.DataFrame(columns=columns)
    frame = frame[~in_sample(frame)].copy()
    frame["profile"] = frame["profile"].fillna("?")
    frame["variant"] = frame["variant"].fillna("") if "variant" in frame else ""
    frame["track"] = frame["track"].fillna(DEFAULT_TRACK) if "track" in frame else DEFAULT_TRACK
    rows = []
    samples: list[np.ndarray] = []  # every cell's values over seeds, in (row, metric) order
    for (profile, system, model, variant, track), group in frame.groupby(
        [*BOARD_KEY, "variant", "track"], dropna=False, sort=False
    ):
        _refuse_repeated_seeds(group)
        counts = {s: int((group["status"] == s).sum()) for s in STATUSES}
        seeds = sorted({int(s) for s in group["seed"].dropna()})
        backends = [b for b in group["backend"].dropna().unique()] if "backend" in group else []
        families = [f for f in group["family"].dropna().unique()] if "family" in group else []
        ranked = bool(flag_column(group, "ranked", True).all())
        roles = (
            [r for r in group["reference"].fillna("").unique() if r] if "reference" in group else []
        )
        row: dict[str, Any] = {
            "profile": profile,
            "system": system,
            "model": model,
            "variant": variant,
            "track": track,
            "backend": backends[0] if backends else "",
            "family": families[0] if families else "",
            "ranked": ranked,
            "reference": roles[0] if roles else "",
            "n_seeds": len(group),
            "seeds": ";".join(str(s) for s in seeds),
            **{f"n_{s}": counts[s] for s in STATUSES},
            "n_untrained": int((group["trained"] == False).sum())  # noqa: E712
            if "trained" in group
            else 0,
            # seeds whose criterion still fell over the last 20% of steps
            "n_unconverged": int((group["converged"] == False).sum())  # noqa: E712
            if "converged" in group
            else 0,
            "status": status_text(counts),
            "reason": reason_text(group),
        }
        use = group[group["status"] == "ok"]
        if use.empty:
            use = group[group["status"] == "diverged"]
        for m in metrics:
            mean, std = _agg(use[m]) if (m in use and not use.empty) else (math.nan, math.nan)
            row[f"{m}_mean"], row[f"{m}_std"] = mean, std
            samples.append(seed_values(use[m]) if m in use else np.array([]))
        timed = use if not use.empty else group
        for t in TIMINGS:
            vals = pd.to_numeric(timed[t], errors="coerce") if t in timed else pd.Series([])
            row[f"{t}_mean"] = float(vals.mean()) if vals.notna().any() else math.nan
        if tracks:
            row["tuning_cpu_s"] = tuning_cpu(group)
        row["git_commits"] = _distinct(group.get("git_commit"))
        row["machines"] = _distinct(group.get("machine"))
        row["dates"] = _distinct(
            None if "created_at" not in group else group["created_at"].astype(str).str[:10]
        )
        rows.append(row)
    intervals = iter(stats.mean_intervals(samples))
    for row in rows:
        for m in metrics:
            row[f"{m}_ci_low"], row[f"{m}_ci_high"] = next(intervals)
    out = pd.DataFrame(rows, columns=columns)
    systems = registry.ordered("system", out["system"].astype(str))
    models = registry.ordered("model", out["model"].astype(str))
    keys = out.apply(
        lambda r: (
            str(r["profile"]),
            _track_rank(str(r["track"])) if tracks else (),
            systems.index(str(r["system"])),
            models.index(str(r["model"])),
            variant_sort_key(r["variant"]) if variants else (),
        ),
        axis=1,
    )
    return out.iloc[sorted(range(len(out)), key=lambda i: keys.iloc[i])].reset_index(drop=True)


def _track_rank(track: str) -> tuple[int, str]:
    """Tracks in :data:`TRACKS` order (protocol first), unknown ones after."""
    return (TRACKS.index(track), "") if track in TRACKS else (len(TRACKS), track)


def _distinct(values: Any) -> str:
    """Distinct non-empty values, sorted, ``;``-joined."""
    if values is None:
        return ""
    return ";".join(
        sorted({str(v) for v in values if v is not None and str(v) not in ("", "nan", "None")})
    )


def format_value(mean: float, std: float = math.nan, linear: bool = False) -> str:
    """``3.7e-02 ± 1.1e-03``; ``inf``; ``—`` for no value; mean alone for one seed."""

    def one(x: float) -> str:
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return f"{x:.3g}" if linear else f"{x:.1e}"

    if mean is None or pd.isna(mean):
        return "—"
    text = one(float(mean))
    if std is not None and not pd.isna(std) and not math.isinf(float(mean)):
        text += f" ± {one(float(std))}"
    return text


def format_interval(
    mean: float, low: float = math.nan, high: float = math.nan, linear: bool = False
) -> str:
    """``3.7e-02 [3.5e-02, 3.9e-02]`` (the mean over seeds and its interval); the mean
    alone where there is no interval (one seed; ``inf``: a diverged rollout); ``—`` for
    no value."""
    text = format_value(mean, linear=linear)
    if (
        text == "—"
        or math.isinf(float(mean))
        or low is None
        or high is None
        or pd.isna(low)
        or pd.isna(high)
    ):
        return text
    return f"{text} [{format_value(low, linear=linear)}, {format_value(high, linear=linear)}]"


def short_reason(text: Any, width: int = 72) -> str:
    """A table's reason cell: the text cut to ``width`` characters (``…``); ``""`` for
    none. The CSV keeps the whole text."""
    if text is None or (isinstance(text, float) and math.isnan(text)):
        return ""
    text = " ".join(str(text).split())
    return text if len(text) <= width else text[: width - 1].rstrip() + "…"


def board_metrics(board: pd.DataFrame) -> list[str]:
    """The metrics of a leaderboard (its ``<metric>_mean`` columns, timings apart), in
    column order."""
    return [
        c[: -len("_mean")]
        for c in board.columns
        if c.endswith("_mean") and c[: -len("_mean")] not in TIMINGS
    ]


def display_frame(
    board: pd.DataFrame, timings: bool = True, ids: Sequence[str] = ("system", "model")
) -> pd.DataFrame:
    """The leaderboard with ``mean [low, high]`` strings (:func:`format_interval`), for
    Markdown and HTML: the ``ids`` columns, ``variant`` where the board has one,
    ``n_seeds``, ``status``, ``reason`` (cut short: :func:`short_reason`; only when some
    row has one), every metric that has a value somewhere, and ``cpu_s``."""
    metrics = board_metrics(board)
    linear = linear_metrics()
    reasons = bool(text_column(board, "reason").ne("").any())
    rows = []
    for _, r in board.iterrows():
        row: dict[str, Any] = {c: r[c] for c in ids}
        if "variant" in board:
            row["variant"] = r["variant"] if isinstance(r["variant"], str) else ""
        if "track" in board:
            row["track"] = r["track"] if isinstance(r["track"], str) else DEFAULT_TRACK
        row.update(n_seeds=int(r["n_seeds"]), status=r["status"])
        if reasons:
            row["reason"] = short_reason(r["reason"])
        for m in metrics:
            if board[f"{m}_mean"].isna().all():  # not applicable anywhere
                continue
            row[m] = format_interval(
                r[f"{m}_mean"],
                r.get(f"{m}_ci_low", math.nan),
                r.get(f"{m}_ci_high", math.nan),
                linear=m in linear,
            )
        if timings:
            row[COST_COLUMN] = format_value(r.get(f"{COST_COLUMN}_mean", math.nan), linear=True)
        if timings and "tuning_cpu_s" in board:
            row["tuning_cpu_s"] = format_value(r.get("tuning_cpu_s", math.nan), linear=True)
        rows.append(row)
    return pd.DataFrame(rows)
