"""What checkpoint selection resolved: the validation criterion's paired noise against the
differences between checkpoints, and whether training converged (docs/METRICS.md,
"Checkpoint selection").

Every record of schema 3 carries, in ``selection``, the criterion's value at the lowest,
the final and the late (80 %) checkpoint, with the paired standard errors of final -
lowest and late - final (the checkpoints share the validation points, so a difference
is judged point by point). :func:`selection_frame` summarises them per (profile, track,
system, family): how many paired standard errors the lowest checkpoint beats the final
one by, how often the rule scored an earlier checkpoint, how far the criterion moved
over the last 20 % of steps, and how many seeds converged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from hnnbench import _registry as registry
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._results.report.markdown import md_cell
from hnnbench._results.report.tables import md_table

__all__ = ["selection_frame", "selection_markdown"]

#: The columns of :func:`selection_frame`.
COLUMNS = (
    "profile",
    "track",
    "system",
    "family",
    "criterion",
    "runs",
    "points",
    "rel_se",
    "gap_z",
    "earlier",
    "at",
    "late_z",
    "converged",
)


def _num(value: Any) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return math.nan
    return out


def _ratio(a: float, b: float) -> float:
    return a / b if math.isfinite(a) and math.isfinite(b) and b > 0 else math.nan


def selection_frame(records: Sequence[dict[str, Any]]) -> pd.DataFrame:
    """One row per (profile, track, system, family) of the trained records that name
    their criterion (schema 3), with:

    - ``criterion``, ``runs`` (seeds), ``points`` (median validation points or windows);
    - ``rel_se``: the median paired standard error of late - final over the final
      value: the noise of a checkpoint difference, relative to the criterion;
    - ``gap_z``: the median of (final - lowest) / its paired standard error: how many
      standard errors the lowest checkpoint beats the final one by (the rule scores it
      above 2);
    - ``earlier``: the seeds whose scored checkpoint is not the final one;
    - ``at``: the median fraction of the steps at the scored checkpoint (1: the final
      one, the criterion still falling or flat; far below 1: it rose as training went
      on);
    - ``late_z``: the median of (late - final) / its paired standard error: how far the
      criterion still fell over the last 20 % of steps;
    - ``converged``: the seeds whose criterion stopped improving (``late_z <= 2``).
    """
    rows: dict[tuple[str, ...], list[dict[str, float]]] = {}
    names: dict[tuple[str, ...], str] = {}
    for rec in records:
        sel = rec.get("selection")
        if not isinstance(sel, dict) or not sel.get("criterion") or rec.get("status") != "ok":
            continue
        key: tuple[str, ...] = (
            str(rec.get("profile", "")),
            str(rec.get("track") or DEFAULT_TRACK),
            str(rec.get("system", "")),
            str(rec.get("family") or rec.get("model", "")),
        )
        names[key] = str(sel["criterion"])
        final, best = _num(sel.get("final_value")), _num(sel.get("best_value"))
        late = _num(sel.get("late_value"))
        final_se, late_se = _num(sel.get("final_se")), _num(sel.get("late_se"))
        rows.setdefault(key, []).append(
            {
                "points": _num(sel.get("points")),
                "rel_se": _ratio(late_se, abs(final)),
                "gap_z": _ratio(final - best, final_se) if final != best else 0.0,
                "earlier": float(sel.get("step") != sel.get("final_step")),
                "at": _ratio(_num(sel.get("step")), _num(sel.get("final_step"))),
                "late_z": _ratio(late - final, late_se),
                "converged": float(sel.get("converged") is True),
            }
        )
    out = []
    for key, runs in rows.items():
        frame = pd.DataFrame(runs)

        def median(col: str, frame: pd.DataFrame = frame) -> float:
            values = frame[col].to_numpy(dtype=float)
            values = values[np.isfinite(values)]
            return float(np.median(values)) if values.size else math.nan

        out.append(
            {
                "profile": key[0],
                "track": key[1],
                "system": key[2],
                "family": key[3],
                "criterion": names[key],
                "runs": len(runs),
                "points": median("points"),
                "rel_se": median("rel_se"),
                "gap_z": median("gap_z"),
                "earlier": int(frame["earlier"].sum()),
                "at": median("at"),
                "late_z": median("late_z"),
                "converged": int(frame["converged"].sum()),
            }
        )
    if not out:
        return pd.DataFrame(columns=list(COLUMNS))
    frame = pd.DataFrame(out)
    systems = registry.ordered("system", frame["system"].astype(str))
    frame["_s"] = [systems.index(s) for s in frame["system"]]
    return (
        frame.sort_values(["profile", "track", "_s", "family"], kind="stable")
        .drop(columns="_s")
        .reset_index(drop=True)[list(COLUMNS)]
    )


def selection_markdown(frame: pd.DataFrame) -> str:
    """:func:`selection_frame` as a Markdown section (its rule first)."""
    lines = [
        "Each run is scored at its final checkpoint unless the lowest one beats it on the "
        "validation criterion by more than 2 paired standard errors (docs/METRICS.md, "
        '"Checkpoint selection"). Per system and family, medians over seeds: `rel_se`, '
        "the paired standard error of a checkpoint difference relative to the criterion; "
        "`gap_z`, how many standard errors the lowest checkpoint beats the final one by; "
        "`earlier`, the seeds scored at an earlier checkpoint; `at`, the fraction of the "
        "steps at the scored checkpoint (1: the final one); `late_z`, how many "
        "standard errors the criterion still fell over the last 20% of steps; "
        "`converged`, the seeds where it stopped falling (`late_z` <= 2).",
        "",
    ]
    if frame.empty:
        return (
            "\n".join([*lines, "No record names its selection criterion (records of schema 3 do)."])
            + "\n"
        )
    shown = frame.copy()
    for col in ("rel_se", "gap_z", "late_z"):
        shown[col] = [("—" if not math.isfinite(v) else f"{v:.3g}") for v in shown[col]]
    shown["at"] = [("—" if not math.isfinite(v) else f"{v:.2f}") for v in shown["at"]]
    shown["points"] = [("—" if not math.isfinite(v) else f"{v:g}") for v in shown["points"]]
    shown["earlier"] = [f"{e}/{n}" for e, n in zip(shown["earlier"], shown["runs"], strict=True)]
    shown["converged"] = [
        f"{c}/{n}" for c, n in zip(shown["converged"], shown["runs"], strict=True)
    ]
    if shown["track"].eq(DEFAULT_TRACK).all():
        shown = shown.drop(columns="track")
    if shown["profile"].nunique() == 1:
        shown = shown.drop(columns="profile")
    shown = shown.map(md_cell)
    return "\n".join(lines) + "\n" + md_table(shown) + "\n"
