"""Report figures, declared in a registry (:data:`FIGURES`, :func:`figure`).

Two scopes:

- ``"system"``: one figure per (profile, system, variant) from the runs' rollout arrays
  (``rollout.npz``) of the lowest seed: phase portraits, the true energy along each
  rollout, the learned conserved quantity, loss curves;
- ``"board"``: figures of the whole leaderboard, or of records across variants: rank
  heatmaps (families x systems, with a distinct mark for a pair not run, skipped,
  failed, timed out, diverged or not applicable), the performance profiles of the
  aggregate, and the metric against a swept numeric setting (e.g. the training-set
  size, ``system.n_traj=10,25,50,100``).

Styles come from record fields (family, backend; :mod:`hnnbench._results.report.style`) and
order from the registry; nothing here names a model or system.
"""

from __future__ import annotations

import hashlib
import logging
import math
import multiprocessing
import os
import re
import sys
import textwrap
import zipfile
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Optional, cast

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts.errors import UnsafePathError
from hnnbench._contracts.names import DEFAULT_TRACK, REFERENCES, TRACKS, name_problem
from hnnbench._contracts.paths import safe_join
from hnnbench._contracts.plugin import HISTORY_TRAIN, HISTORY_VALID
from hnnbench._record.tracks import on_trial_seed, track_of
from hnnbench._results.families import family_order
from hnnbench._results.leaderboard import (
    flag_column,
    format_value,
    metric_declarations,
    text_column,
    variant_labels,
    variant_overrides,
)
from hnnbench._results.report import style
from hnnbench._results.report.verdicts import main_scope, scope_label, scopes

log = logging.getLogger("hnnbench")

__all__ = [
    "CELL_STATES",
    "FIGURES",
    "PROFILE_FIGURE",
    "FigureKind",
    "Made",
    "Run",
    "SystemRuns",
    "cell_states",
    "figure",
    "figure_arrays",
    "main_profile_figure",
    "make_figures",
    "rank_table",
    "runs_for_figures",
    "slug",
]

#: How many evaluation trajectories the rollout figures show.
N_TRAJ_SHOWN = 3
#: The most time points per trajectory a published figure rollout keeps
#: (:func:`figure_arrays`).
FIGURE_POINTS = 200
#: The arrays of a rollout file that the system figures draw.
FIGURE_ARRAYS = ("t", "states_true", "states_hat", "energy_true", "energy_hat", "learned_energy")
#: The evaluation trajectories' colours in the phase portraits (Okabe & Ito's blue,
#: orange and bluish green: told apart with any colour vision).
_TRAJ_COLORS = ("#0072B2", "#E69F00", "#009E73")
#: The most panels a figure puts side by side; more wrap into further rows, so that a
#: figure of many models keeps readable panels and labels.
MAX_COLUMNS = 4


def _plotted(kind: str) -> list[str]:
    """The installed metrics whose declaration asks for board figure ``kind``."""
    return [m.name for m in registry.metrics() if kind in m.figures]


@dataclass(eq=False)  # compared by identity: the arrays make field equality ambiguous
class Run:
    model: str
    backend: str
    family: str
    seed: int
    status: str
    arrays: dict[str, np.ndarray]


@dataclass
class SystemRuns:
    """The runs a system-scope figure draws: one per model, of the lowest seed."""

    label: str
    seed: int
    runs: list[Run]
    #: Models that ran on the system but have no rollout file to draw.
    missing: list[str] = field(default_factory=list)

    def note(self) -> str:
        """``"; no rollout: a, b"`` for a figure's title, or ``""``."""
        return f"; no rollout: {', '.join(self.missing)}" if self.missing else ""

    @property
    def models(self) -> list[str]:
        return [r.model for r in self.runs]

    def families(self) -> dict[str, str]:
        return {r.model: r.family for r in self.runs if r.family}

    def line(self, run: Run) -> dict[str, Any]:
        backends = list(dict.fromkeys(r.backend for r in self.runs))  # runs: registry order
        return style.line(run.model, run.backend, self.families(), self.models, backends)

    def color(self, model: str) -> str:
        return style.color(model, self.families(), self.models)


@dataclass(frozen=True)
class FigureKind:
    """One kind of figure: its file-name part, title and drawing function."""

    name: str
    title: str
    scope: Literal["system", "board"]
    make: Callable[..., Any]


#: Every figure kind, in page order.
FIGURES: dict[str, FigureKind] = {}


def figure(
    name: str, title: str, scope: Literal["system", "board"] = "system"
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Register a figure kind. A ``"system"`` figure is ``make(SystemRuns) -> Figure |
    None``; a ``"board"`` figure is ``make(board, records, verdicts) -> {file stem:
    Figure}`` (``verdicts``: :class:`hnnbench._results.report.verdicts.Verdicts`, or ``None``)."""

    def register(make: Callable[..., Any]) -> Callable[..., Any]:
        FIGURES[name] = FigureKind(name, title, scope, make)
        return make

    return register


# --------------------------------------------------------------------------- inputs


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a rollout file, read bounded (:func:`hnnbench._record.store.load_arrays`:
    no decompression bomb, no objects, no link or device); ``{}`` with a warning naming
    the file when it cannot be read."""
    try:
        return {k: np.asarray(v) for k, v in records.load_arrays(path).items()}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, records.UnsafeFile) as err:
        log.warning("cannot read %s: %s", path, " ".join(str(err).split()))
        return {}


def figure_arrays(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """What the system figures draw of a rollout file, made small enough to publish with
    the records: the first :data:`N_TRAJ_SHOWN` trajectories of :data:`FIGURE_ARRAYS`,
    at most :data:`FIGURE_POINTS` time points each (evenly spaced, the first and last
    kept), and the training history, all as float32. The figures drawn from it are
    those of the full file up to the thinning of the time grid."""
    out: dict[str, np.ndarray] = {}
    t = np.asarray(arrays.get("t", np.zeros(0)))
    keep = (
        np.unique(np.linspace(0, t.size - 1, min(t.size, FIGURE_POINTS)).round().astype(int))
        if t.size
        else np.zeros(0, dtype=int)
    )
    for key, value in arrays.items():
        value = np.asarray(value)
        if key == "t":
            value = value[keep]
        elif key in FIGURE_ARRAYS and value.ndim >= 2 and value.shape[1] == t.size:
            value = value[:N_TRAJ_SHOWN][:, keep]
        elif not key.startswith("history."):
            continue
        out[key] = value.astype(np.float32) if value.dtype.kind == "f" else value
    return out


def runs_for_figures(recs: list[dict[str, Any]]) -> tuple[Optional[int], list[Run]]:
    """The lowest seed with a rollout file, and each model's run of that seed that has
    one, in registry order (a record without one, e.g. a published record whose figure
    rollout was not kept, is left out without a warning; the figures name such models:
    :attr:`SystemRuns.missing`). A tuned run on one of its study's trial seeds
    (:func:`hnnbench._record.tracks.on_trial_seed`) is drawn only where no other seed
    has a rollout, as no row reads it."""
    with_rollout = [
        r
        for r in recs
        if r.get("seed") is not None
        and r.get("path")
        and (Path(r["path"]) / records.ROLLOUT_NAME).exists()
    ]
    unseen = [r for r in with_rollout if not on_trial_seed(r)]
    seeds = sorted({int(r["seed"]) for r in unseen or with_rollout})
    if not seeds:
        return None, []
    seed = seeds[0]
    runs = []
    for rec in recs:
        if rec.get("seed") != seed or rec.get("status") not in ("ok", "diverged"):
            continue
        if not rec.get("path") or not (Path(rec["path"]) / records.ROLLOUT_NAME).exists():
            continue
        arrays = _load_npz(Path(rec["path"]) / records.ROLLOUT_NAME)
        if arrays:
            runs.append(
                Run(
                    str(rec.get("model")),
                    str(rec.get("backend") or ""),
                    str(rec.get("family") or ""),
                    seed,
                    str(rec.get("status")),
                    arrays,
                )
            )
    order = registry.ordered("model", [r.model for r in runs])
    runs.sort(key=lambda r: order.index(r.model))
    return seed, runs


def _new_figure(
    n_panels: int, width: float = 4.6, height: float = 3.6, max_columns: int = MAX_COLUMNS
) -> Any:
    """A figure of ``n_panels`` panels of ``width`` x ``height`` inches, at most
    ``max_columns`` in a row (more wrap into further rows); returns it and its used
    axes (the rest of the last row is hidden)."""
    n_panels = max(int(n_panels), 1)
    columns = min(n_panels, max(int(max_columns), 1))
    rows = -(-n_panels // columns)
    fig = Figure(figsize=(max(width * columns, 5.0), height * rows), layout="constrained")
    axes = list(fig.subplots(rows, columns, squeeze=False).ravel())
    for ax in axes[n_panels:]:
        ax.set_visible(False)
    return fig, axes[:n_panels]


def _fit_suptitle(fig: Any) -> None:
    """Wrap the figure's title to its width (a figure of few panels cut it off)."""
    title = getattr(fig, "_suptitle", None)
    if title is None or not title.get_text():
        return
    # centred on the figure: clear of a legend beside the panels (about 1.8 in) on both sides
    width = max(fig.get_figwidth() - 3.6 * bool(fig.legends), 3.0)
    per_line = int(width * 72 / (0.55 * float(title.get_fontsize())))
    if len(title.get_text()) > per_line:
        title.set_text(textwrap.fill(title.get_text(), width=max(per_line, 20)))


def _save(fig: Any, path: Path) -> Path:
    _fit_suptitle(fig)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=100, format="png")
    tmp.replace(path)
    return path


# --------------------------------------------------------------------------- system scope


@figure("phase", "Phase portraits (q1 vs p1)")
def phase_figure(ctx: SystemRuns) -> Any:
    shown = [r for r in ctx.runs if "states_hat" in r.arrays and "states_true" in r.arrays]
    if not shown:
        return None
    n_traj = min(N_TRAJ_SHOWN, shown[0].arrays["states_true"].shape[0])
    fig, axes = _new_figure(len(shown), width=3.8, height=3.4)
    for ax, run in zip(axes, shown, strict=True):
        true, hat = run.arrays["states_true"], run.arrays["states_hat"]
        n = true.shape[-1] // 2
        for k in range(min(n_traj, true.shape[0])):
            c = _TRAJ_COLORS[k % len(_TRAJ_COLORS)]
            ax.plot(hat[k, :, 0], hat[k, :, n], "-", color=c, lw=2.0, alpha=0.75, zorder=2)
            ax.plot(true[k, :, 0], true[k, :, n], "--", color="k", lw=0.9, zorder=3)
            ax.plot(true[k, 0, 0], true[k, 0, n], "o", color=c, ms=5, mec="k", zorder=4)
        ax.set_title(run.model, color=ctx.color(run.model))
        ax.set_xlabel("q1")
        ax.set_ylabel("p1")
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], color="k", ls="--", lw=0.9, label="true")]
    handles += [
        Line2D([], [], color=_TRAJ_COLORS[k], lw=2.0, label=f"rollout, trajectory {k + 1}")
        for k in range(n_traj)
    ]
    handles.append(Line2D([], [], color="w", marker="o", mec="k", mfc="0.6", label="start"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8)
    fig.suptitle(
        f"{ctx.label}: phase portraits (q1, p1) of evaluation trajectories 1–{n_traj}, "
        f"true vs model rollout (seed {ctx.seed}){ctx.note()}"
    )
    return fig


@figure("energy", "True energy along rollouts")
def energy_figure(ctx: SystemRuns) -> Any:
    shown = [r for r in ctx.runs if "energy_hat" in r.arrays]
    if not shown:
        return None
    ref = shown[0].arrays
    t, e_true = ref["t"], ref["energy_true"]
    n_traj = min(N_TRAJ_SHOWN, e_true.shape[0])
    fig, axes = _new_figure(n_traj)
    for k, ax in enumerate(axes):
        ax.plot(t, e_true[k], "k--", lw=2.0, label="ground truth")
        for run in shown:
            ax.plot(run.arrays["t"], run.arrays["energy_hat"][k], label=run.model, **ctx.line(run))
        ax.set_title(f"trajectory {k + 1}")
        ax.set_xlabel("time")
        ax.set_ylabel("true energy E(x̂(t))")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=8)
    missing = [*(r.model for r in ctx.runs if r not in shown), *ctx.missing]
    note = f"; no rollout: {', '.join(missing)}" if missing else ""
    fig.suptitle(f"{ctx.label}: true energy along each model's rollout (seed {ctx.seed}){note}")
    return fig


@figure("learned_energy", "Learned conserved quantity")
def learned_energy_figure(ctx: SystemRuns) -> Any:
    shown = [r for r in ctx.runs if "learned_energy" in r.arrays]
    if not shown:
        return None
    n_traj = min(N_TRAJ_SHOWN, shown[0].arrays["learned_energy"].shape[0])
    fig, axes = _new_figure(n_traj)
    for k, ax in enumerate(axes):
        for run in shown:
            h = run.arrays["learned_energy"][k]
            ax.plot(run.arrays["t"], h - h[0], label=run.model, **ctx.line(run))
        ax.axhline(0.0, color="k", lw=0.8, ls=":")
        ax.set_title(f"trajectory {k + 1}")
        ax.set_xlabel("time")
        ax.set_ylabel("H(x̂(t)) − H(x̂(0))")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=8)
    fig.suptitle(
        f"{ctx.label}: learned conserved quantity along its own rollout, shifted to "
        f"start at 0 (seed {ctx.seed}){ctx.note()}"
    )
    return fig


@figure("loss", "Loss curves")
def loss_figure(ctx: SystemRuns) -> Any:
    shown = [r for r in ctx.runs if "history.step" in r.arrays and r.arrays["history.step"].size]
    if not shown:
        return None
    fig, axes = _new_figure(1, width=7.0, height=4.2)
    ax = axes[0]
    for run in shown:
        step = run.arrays["history.step"]
        color = ctx.color(run.model)
        for key, ls, label in (
            (f"history.{HISTORY_TRAIN}", "-", "train"),
            (f"history.{HISTORY_VALID}", "--", "validation"),
            ("history.test_loss", ":", "test"),
        ):  # before the validation split
            if key in run.arrays and run.arrays[key].size == step.size:
                y = np.where(run.arrays[key] > 0, run.arrays[key], np.nan)
                ax.plot(step, y, ls, color=color, lw=1.3, label=f"{run.model} {label}")
    ax.set_yscale("log")
    ax.set_xlabel("training step")
    ax.set_ylabel("loss")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=7, ncol=2)
    ax.set_title(f"{ctx.label}: training and validation loss (seed {ctx.seed}){ctx.note()}")
    return fig


# --------------------------------------------------------------------------- board scope

#: How a heatmap cell that holds no rank looks: ``(face colour, text, text colour)``.
CELL_STATES: dict[str, tuple[str, str, str]] = {
    "not run": ("#ffffff", "not run", "0.55"),
    "skipped": ("#d9d9d9", "skipped", "0.25"),
    "failed": ("#f4a6a6", "failed", "k"),
    "timeout": ("#f9d29d", "timeout", "k"),
    "n/a": ("#f2f2f2", "n/a", "0.45"),
}
#: A diverged pair (its mean is ``inf``) keeps its rank, on this colour.
DIVERGED_COLOR = "#1a1a1a"
#: The colour map of ranks (rank 1, the best, at its bright end): viridis, readable
#: with any colour vision and in greyscale (no red-green scale).
RANK_CMAP = "viridis_r"
#: A cell's mark after its rank: best (separated by the sign test) and tied (not
#: separated from the leader), as in the family table.
RANK_MARKS = {"best": " \u2605", "tied": " ="}
#: The face colour of a reference row (standing still, the oracle: never ranked) and the
#: mark of a standing-still cell that no family beats (the family table's ``unbeaten``).
REFERENCE_COLOR = "#eeeeee"
UNBEATEN_MARK = " \u25b2"


def reference_table(board: pd.DataFrame, metric: str, systems: Sequence[str]) -> pd.DataFrame:
    """references x systems: the mean of each reference row (a model that declares a
    ``reference`` role: standing still, the oracle) of a family board, NaN where it has
    none; no row for a reference without a value on any of these systems."""
    if "reference" not in board or f"{metric}_mean" not in board:
        return pd.DataFrame(columns=list(systems), dtype=float)
    rows = board[text_column(board, "reference") != ""]
    rows = rows[text_column(rows, "variant") == ""]
    if rows.empty:
        return pd.DataFrame(columns=list(systems), dtype=float)
    key = "family" if "family" in rows else "model"
    values = rows.pivot_table(
        index=key, columns="system", values=f"{metric}_mean", aggfunc="first", dropna=False
    )
    roles = rows.drop_duplicates(key).set_index(key)["reference"].astype(str)
    order = sorted(
        roles.index,
        key=lambda n: (
            REFERENCES.index(roles[n]) if roles[n] in REFERENCES else len(REFERENCES),
            n,
        ),
    )
    values = values.reindex(index=order, columns=list(systems)).astype(float)
    return values[values.notna().any(axis=1)]  # a reference with no value here: no row


def _family_rows(board: pd.DataFrame) -> pd.DataFrame:
    rows = board[flag_column(board, "ranked", True)]
    rows = rows[text_column(rows, "variant") == ""]
    return rows


def rank_table(board: pd.DataFrame, metric: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``(ranks, values)``: families x systems of a family board
    (:attr:`hnnbench._results.families.Families.board`; a leaderboard's rows are ranked by
    model); rank 1 is the best ranked family of the system (ties share a rank; ``inf``,
    a diverged rollout, ranks last), NaN where the pair has no value."""
    declared = metric_declarations()
    higher = declared[metric].better == "higher" if metric in declared else False
    rows = _family_rows(board)
    key = "family" if "family" in rows and "seeds_from" in rows else "model"
    systems = registry.ordered("system", rows["system"].astype(str))
    names = (
        family_order(rows)
        if key == "family"
        else registry.ordered("model", rows["model"].astype(str))
    )
    values = rows.pivot_table(
        index=key, columns="system", values=f"{metric}_mean", aggfunc="first", dropna=False
    ).reindex(index=names, columns=systems)
    ranks = values.rank(axis=0, ascending=not higher, method="min")
    return ranks, values


def cell_states(
    board: pd.DataFrame, metric: str, index: Sequence[str], columns: Sequence[str]
) -> pd.DataFrame:
    """families x systems: why a heatmap cell holds no rank (a key of
    :data:`CELL_STATES`), ``"diverged"`` for an ``inf`` mean, ``""`` for a value."""
    rows = _family_rows(board)
    out = pd.DataFrame("not run", index=list(index), columns=list(columns))
    for _, r in rows.iterrows():
        family, system = str(r["family"]), str(r["system"])
        if family not in out.index or system not in out.columns:
            continue
        n = int(r.get("n_seeds", 0) or 0)
        value = pd.to_numeric(r.get(f"{metric}_mean"), errors="coerce")
        if n and int(r.get("n_skipped", 0) or 0) == n:
            state = "skipped"
        elif pd.isna(value) and int(r.get("n_timeout", 0) or 0):
            state = "timeout"
        elif pd.isna(value) and int(r.get("n_failed", 0) or 0):
            state = "failed"
        elif pd.isna(value):
            state = "n/a"
        elif math.isinf(float(value)):
            state = "diverged"
        else:
            state = ""
        out.at[family, system] = state
    return out


@figure("heatmap", "Which family wins where: rank by metric", scope="board")
def heatmap_figures(
    board: pd.DataFrame, recs: Sequence[dict[str, Any]], verdicts: Any = None
) -> dict[str, Any]:
    board = getattr(getattr(verdicts, "families", None), "board", None)
    if board is None or board.empty:
        return {}
    out = {}
    several = len(scopes(board)) > 1  # then every heatmap names its scope
    for main, fams in scopes(board, verdicts.main):  # the main scope, then each other
        label = scope_label(fams)
        suffix = "" if main else "_" + slug(label.replace("/", "_"))
        for metric in _plotted("heatmap"):
            if f"{metric}_mean" not in fams or fams[f"{metric}_mean"].isna().all():
                continue
            ranks, values = rank_table(fams, metric)
            if ranks.shape[0] < 2 or values.isna().all().all():
                continue  # a ranking needs two families
            states = cell_states(fams, metric, list(values.index), list(values.columns))
            marks = _marks(fams, metric)
            refs = reference_table(fams, metric, list(values.columns))
            out[f"heatmap_{metric}{suffix}"] = _heatmap(
                ranks, values, states, marks, metric, label if several else "", refs
            )
    return out


def _marks(board: pd.DataFrame, metric: str) -> dict[tuple[str, str], str]:
    """``{(family, system): mark}``: the best and tied marks of the ranked rows, and the
    ``unbeaten`` mark of a reference row (no family beats standing still)."""
    if f"{metric}_mark" not in board:
        return {}
    rows = board[text_column(board, "variant") == ""]
    return {
        (str(r["family"]), str(r["system"])): str(r[f"{metric}_mark"])
        for _, r in rows.iterrows()
        if str(r[f"{metric}_mark"] or "") in ("best", "tied", "unbeaten")
    }


def _heatmap(
    ranks: pd.DataFrame,
    values: pd.DataFrame,
    states: pd.DataFrame,
    marks: dict[tuple[str, str], str],
    metric: str,
    scope: str = "",
    refs: Optional[pd.DataFrame] = None,
) -> Any:
    """The rank heatmap of the ranked families, with the reference rows (standing still,
    the oracle) below a line: their means on grey, never ranked."""
    import matplotlib as mpl
    from matplotlib.patches import Patch

    refs = refs if refs is not None else pd.DataFrame(columns=values.columns, dtype=float)
    n_rows, n_systems = ranks.shape
    n_refs = len(refs.index)
    width = max(6.0, 1.05 * n_systems + 2.5)
    fig, (ax,) = _new_figure(1, width=width, height=max(3.0, 0.42 * (n_rows + n_refs) + 2.0))
    worst = max(float(np.nanmax(ranks.to_numpy())), 2.0) if ranks.notna().any().any() else 2.0
    shade = ((ranks - 1) / (worst - 1)).to_numpy(dtype=float)
    rgba = mpl.colormaps[RANK_CMAP](np.nan_to_num(shade))
    for i in range(n_rows):
        for j in range(n_systems):
            state = str(states.iat[i, j])
            if state in CELL_STATES:
                rgba[i, j] = mpl.colors.to_rgba(CELL_STATES[state][0])
            elif state == "diverged":
                rgba[i, j] = mpl.colors.to_rgba(DIVERGED_COLOR)
    if n_refs:
        grey = np.array(mpl.colors.to_rgba(REFERENCE_COLOR))
        rgba = np.concatenate([rgba, np.broadcast_to(grey, (n_refs, n_systems, 4))], axis=0)
    ax.imshow(rgba, aspect="auto")
    if n_refs:
        ax.axhline(n_rows - 0.5, color="0.3", lw=1.2)
    linear = metric_declarations().get(metric)
    lin = linear is not None and linear.scale == "linear"
    for i, family in enumerate(values.index):
        for j, system in enumerate(values.columns):
            state = str(states.iat[i, j])
            if state in CELL_STATES:
                ax.text(
                    j,
                    i,
                    CELL_STATES[state][1],
                    ha="center",
                    va="center",
                    fontsize=7,
                    color=CELL_STATES[state][2],
                )
                continue
            v, r = float(cast(float, values.iat[i, j])), float(cast(float, ranks.iat[i, j]))
            mark = marks.get((str(family), str(system)), "")
            text = "diverged" if state == "diverged" else format_value(v, linear=lin)
            red, green, blue = rgba[i, j][:3]  # white text on a dark cell, black on a light
            dark = 0.2126 * red + 0.7152 * green + 0.0722 * blue < 0.45
            ax.text(
                j,
                i,
                f"{int(r)}{RANK_MARKS.get(mark, '')}\n{text}",
                ha="center",
                va="center",
                fontsize=7,
                color="w" if dark else "k",
                fontweight="bold" if mark == "best" else "normal",
            )
    ax.set_xticks(
        range(n_systems), [str(s) for s in values.columns], rotation=35, ha="right", fontsize=8
    )
    lin_ref = lin
    for k, reference in enumerate(refs.index):
        for j, system in enumerate(refs.columns):
            v = float(cast(float, refs.iat[k, j]))
            mark = UNBEATEN_MARK if marks.get((str(reference), str(system))) == "unbeaten" else ""
            text = "—" if math.isnan(v) else format_value(v, linear=lin_ref)
            ax.text(j, n_rows + k, f"ref{mark}\n{text}", ha="center", va="center", fontsize=7)
    labels = [str(m) for m in values.index] + [f"{r} (reference)" for r in refs.index]
    ax.set_yticks(range(n_rows + n_refs), labels, fontsize=8)
    title = (
        f"{scope}: "
        * bool(scope)
        + f"Rank of each family by {metric} within each system (1 = best, the mean "
        "below; \u2605 best: separated from every other family by the sign test; "
        "= tied: not separated from the leader)"
        + (
            "; below the line, the references' means, never ranked (\u25b2: no family "
            "beats standing still)"
            if n_refs
            else ""
        )
    )
    ax.set_title(textwrap.fill(title, width=int(width * 11)), fontsize=9)  # ~11 chars/inch
    handles = [Patch(facecolor=DIVERGED_COLOR, label="diverged (inf)")]
    handles += [Patch(facecolor=c, edgecolor="0.6", label=t) for c, t, _ in CELL_STATES.values()]
    fig.legend(
        handles=handles, loc="outside lower center", ncol=len(handles), fontsize=7, frameon=False
    )
    return fig


#: The performance profiles of the main scope (the paper profile's protocol track where
#: there is one: :func:`hnnbench._results.report.verdicts.main_scope`); another scope's file is
#: ``performance_profile_<profile>[_<track>]``.
PROFILE_FIGURE = "performance_profile"


@figure(
    "profile", "Performance profiles: the share of runs above each normalised score", scope="board"
)
def profile_figures(
    board: pd.DataFrame, recs: Sequence[dict[str, Any]], verdicts: Any = None
) -> dict[str, Any]:
    """One panel per headline metric: per family, the share of its (system, seed) runs
    whose normalised score exceeds tau, with the stratified bootstrap's 95% band
    (:mod:`hnnbench._results.aggregate`)."""
    agg = getattr(verdicts, "aggregate", None)
    if (
        agg is None
        or not agg.profiles
        or max(len(curves) for _, curves in agg.profiles.values()) < 2
    ):
        return {}  # a profile compares two families at least
    profiles = list(dict.fromkeys(p for p, _ in agg.profiles))
    main = scope_label(main_scope(agg.iqm, verdicts.main))
    out = {}
    for profile in profiles:
        metrics = [m for p, m in agg.profiles if p == profile]
        fig, axes = _new_figure(len(metrics), width=4.4, height=3.6)
        for ax, metric in zip(axes, metrics, strict=True):
            taus, curves = agg.profiles[(profile, metric)]
            for family, (point, low, high) in curves.items():
                color = style.family_color(family)
                ax.plot(taus, point, color=color, lw=1.6, label=family)
                ax.fill_between(taus, low, high, color=color, alpha=0.15, lw=0)
            ax.axvline(0.0, color="0.5", lw=0.8, ls=":")
            ax.set_xlabel(f"normalised score tau ({agg.baseline} = 0, floor = 1)")
            ax.set_ylabel("share of runs with score > tau")
            ax.set_title(metric, fontsize=9)
            ax.set_ylim(0, 1.02)
            ax.grid(alpha=0.3)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside right upper", fontsize=8)
        fig.suptitle(
            f"{profile}: "
            * (len(profiles) > 1 or profile != main)
            + "Performance profiles over every (system, seed) run, 95% "
            "stratified bootstrap bands",
            fontsize=9,
        )
        out[
            PROFILE_FIGURE
            if profile == main
            else f"{PROFILE_FIGURE}_{slug(profile.replace('/', '_'))}"
        ] = fig
    return out


def _swept_key(recs: Sequence[dict[str, Any]]) -> Optional[str]:
    """The one numeric override whose value differs between the records, or None."""
    labels = variant_labels([variant_overrides(r) for r in recs])
    keys: set[str] = set()
    for label in labels:
        for token in label.split():
            keys.add(token.split("=", 1)[0])
    if len(keys) != 1:
        return None
    key = next(iter(keys))
    for label in labels:
        value = label.partition("=")[2]
        try:
            float(value)
        except ValueError:
            return None
    return key


@figure("sweep", "Metric against a swept setting (e.g. the training-set size)", scope="board")
def sweep_figures(
    board: pd.DataFrame, recs: Sequence[dict[str, Any]], verdicts: Any = None
) -> dict[str, Any]:
    """Per system, each metric of interest against the value of the one numeric setting
    the sweep varied, one line per model (mean ± std over seeds)."""
    key = _swept_key(recs)
    if key is None or "variant" not in board:
        return {}
    out = {}
    declared = metric_declarations()
    for main, scoped in scopes(board, getattr(verdicts, "main", None)):
        label = "" if main else scope_label(scoped)
        for name, fig in _sweep_figures(scoped, key, declared, label).items():
            out[name + ("" if main else "_" + slug(label.replace("/", "_")))] = fig
    return out


def _sweep_figures(
    board: pd.DataFrame, key: str, declared: dict[str, Any], scope: str
) -> dict[str, Any]:
    """:func:`sweep_figures` of one scope's rows (``scope``: its label, ``""`` for the
    main one)."""
    out = {}
    for system in registry.ordered("system", board["system"].astype(str)):
        rows = board[board["system"] == system].copy()
        rows["x"] = rows["variant"].astype(str).str.partition("=")[2].astype(float)
        metrics = [
            m
            for m in _plotted("data_efficiency")
            if f"{m}_mean" in rows and rows[f"{m}_mean"].notna().any()
        ]
        if not metrics or rows["x"].nunique() < 2:
            continue
        fig, axes = _new_figure(len(metrics), width=4.2)
        models = registry.ordered("model", rows["model"].astype(str))
        families = {str(r["model"]): str(r.get("family") or "") for _, r in rows.iterrows()}
        backends = list(
            dict.fromkeys(str(rows[rows["model"] == m]["backend"].iloc[0]) for m in models)
        )
        for ax, metric in zip(axes, metrics, strict=True):
            for model in models:
                sel = rows[rows["model"] == model].sort_values("x")
                backend = str(sel["backend"].iloc[0])
                y = sel[f"{metric}_mean"].to_numpy(dtype=float)
                err = sel[f"{metric}_std"].to_numpy(dtype=float)
                props = style.line(model, backend, families, models, backends)
                ax.errorbar(
                    sel["x"],
                    y,
                    yerr=np.nan_to_num(err),
                    label=model,
                    marker="o",
                    ms=3,
                    capsize=2,
                    **props,
                )
            if metric in declared and declared[metric].scale == "log":
                ax.set_yscale("log")
            ax.set_xscale("log")
            ax.set_xlabel(key)
            ax.set_ylabel(metric)
            ax.grid(alpha=0.3, which="both")
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside right upper", fontsize=7)
        fig.suptitle(
            f"{system}{f' ({scope})' if scope else ''}: metrics against {key} "
            "(mean ± std over seeds)"
        )
        out[f"{system}_sweep_{slug(key)}"] = fig
    return out


# --------------------------------------------------------------------------- driver


def slug(text: str, limit: int = 80) -> str:
    """A file-name form of ``text``; a long one is cut and given a hash of the whole."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", text.replace("=", "-"))
    if len(slug) <= limit:
        return slug
    return f"{slug[:limit]}-{hashlib.sha1(text.encode()).hexdigest()[:10]}"


@dataclass
class Made:
    """One figure written: its section label, kind, and file."""

    label: str
    kind: str
    path: Path
    extra: dict[str, Any] = field(default_factory=dict)

    def __iter__(self) -> Any:  # ``label, kind, path = made``
        return iter((self.label, self.kind, self.path))


def main_profile_figure(made: Sequence[Made]) -> Optional[Path]:
    """The main scope's performance-profile figure among ``made`` (:data:`PROFILE_FIGURE`),
    or ``None``."""
    return next(
        (m.path for m in made if m.kind == "profile" and m.path.stem == PROFILE_FIGURE), None
    )


def make_figures(
    recs: list[dict[str, Any]], board: pd.DataFrame, directory: Path, verdicts: Any = None
) -> list[Made]:
    """Every registered figure into ``directory``: the board figures (given
    ``verdicts``, a :class:`hnnbench._results.report.verdicts.Verdicts`, for the family heatmaps
    and the performance profiles), then each system's (drawn by
    :func:`drawing_processes` processes while this one draws the board's)."""
    directory = Path(directory)

    def board_figures() -> list[Made]:
        made = []
        for kind in FIGURES.values():
            if kind.scope != "board":
                continue
            try:
                figures = kind.make(board, recs, verdicts)
            except Exception as err:  # one broken figure must not stop the report
                log.warning("figure %s failed: %s", kind.name, err)
                continue
            for stem, fig in figures.items():
                try:
                    made.append(
                        Made(
                            "all systems",
                            kind.name,
                            _save(fig, safe_join(directory, f"{stem}.png")),
                        )
                    )
                except UnsafePathError as err:
                    log.warning("figure %s not written: %s", kind.name, err)
        return made

    profiles = sorted({str(r.get("profile")) for r in recs})
    # One figure set per (profile, system, track, variant): a tuned or recipe record is
    # its track's main row (its selected settings are no variant), drawn apart from the
    # protocol's runs of the same models.
    groups: dict[tuple[str, str, str, str], list[dict[str, Any]]] = {}
    for rec, variant in zip(
        recs, variant_labels([variant_overrides(r) for r in recs]), strict=True
    ):
        # A figure's file is named after the system, profile and track: a record whose
        # names are not names draws none (hnnbench._contracts.paths.safe_join refuses it
        # regardless).
        problem = name_problem("system", rec.get("system")) or name_problem(
            "profile", rec.get("profile")
        )
        if problem:
            log.warning("no figures from %s: %s", rec.get("path", "a record"), problem)
            continue
        track = track_of(rec)
        groups.setdefault(
            (str(rec.get("profile")), str(rec.get("system")), track, variant), []
        ).append(rec)
    systems = registry.ordered("system", [k[1] for k in groups])
    tasks = []
    for profile, system, track, variant in sorted(
        groups, key=lambda k: (k[0], systems.index(k[1]), _track_rank(k[2]), k[2], k[3])
    ):
        label = system if len(profiles) == 1 else f"{system} ({profile})"
        stem = system if len(profiles) == 1 else f"{profile}_{system}"
        name = system
        if track != DEFAULT_TRACK:
            label, stem, name = (
                f"{label}, {track} track",
                f"{stem}_{slug(track)}",
                f"{name} ({track})",
            )
        if variant:
            label, stem, name = (
                f"{label} [{variant}]",
                f"{stem}__{slug(variant)}",
                f"{name} [{variant}]",
            )
        tasks.append(
            _SystemTask(
                label, stem, name, system, directory, groups[(profile, system, track, variant)]
            )
        )
    taken: set[str] = set()
    for task in tasks:  # two groups whose names join alike must not share a file
        if task.stem in taken:
            task.stem += "-" + hashlib.sha1(task.label.encode()).hexdigest()[:8]
            log.warning(
                "figures of %s renamed %s: another group's names join alike", task.label, task.stem
            )
        taken.add(task.stem)
    made, per_system = _map(_system_figures, tasks, board_figures)
    for drawn in per_system:
        made += drawn
    return made


def _track_rank(track: str) -> int:
    """Tracks in :data:`hnnbench._contracts.names.TRACKS` order, any other after them."""
    return TRACKS.index(track) if track in TRACKS else len(TRACKS)


@dataclass
class _SystemTask:
    """The system-scope figures of one (profile, system, track, variant): what to draw
    them from and where."""

    label: str
    stem: str
    name: str  # SystemRuns.label
    system: str
    directory: Path
    records: list[dict[str, Any]]


def _system_figures(task: _SystemTask) -> list[Made]:
    """Every system-scope figure of ``task``, drawn and saved."""
    seed, runs = runs_for_figures(task.records)
    if seed is None:
        return []
    drawn = {r.model for r in runs}
    missing = registry.ordered(
        "model",
        {
            str(r.get("model"))
            for r in task.records
            if r.get("status") in ("ok", "diverged") and str(r.get("model")) not in drawn
        },
    )
    ctx = SystemRuns(task.name, seed, runs, missing)
    made = []
    for kind in FIGURES.values():
        if kind.scope != "system":
            continue
        try:
            fig = kind.make(ctx)
        except Exception as err:
            log.warning("figure %s/%s failed: %s", task.system, kind.name, err)
            continue
        if fig is not None:
            try:
                path = _save(fig, safe_join(task.directory, f"{task.stem}_{kind.name}.png"))
            except UnsafePathError as err:
                log.warning("figure %s/%s not written: %s", task.system, kind.name, err)
                continue
            made.append(Made(task.label, kind.name, path))
    return made


def drawing_processes() -> int:
    """How many processes draw the system figures: one per core this process may run
    on (a command pinned to one core, as the basic launcher's is by its first job,
    draws in itself), on Linux, where they fork and so inherit the figure registry;
    one elsewhere."""
    if not sys.platform.startswith("linux") or not hasattr(os, "sched_getaffinity"):
        return 1
    if _jax_started():  # XLA's thread pools do not survive a fork (JAX warns): draw here
        return 1
    return len(os.sched_getaffinity(0))


def _jax_started() -> bool:
    """Whether this process has started a JAX backend (and with it XLA's threads).

    A ``hnnbench`` command's parent process never has (its jobs run in workers), a
    notebook that trained a JAX model in-process has; unknown counts as started."""
    if "jax" not in sys.modules:
        return False
    try:
        from jax._src import xla_bridge

        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):  # another JAX layout: do not risk the fork
        return True


def _map(
    fn: Callable[[_SystemTask], list[Made]],
    tasks: list[_SystemTask],
    meanwhile: Callable[[], list[Made]],
) -> tuple[list[Made], list[list[Made]]]:
    """``(meanwhile(), [fn(t) for t in tasks])``; the tasks in forked processes when
    there are several tasks and cores (the end of a sweep drew its ~46 quick-sweep
    figures one after the other: 41 s of one core of 2), while this process runs
    ``meanwhile``; what a pool could not draw is drawn here."""
    workers = min(drawing_processes(), len(tasks))
    if workers < 2:
        return meanwhile(), [fn(t) for t in tasks]
    out: list[Optional[list[Made]]] = [None] * len(tasks)
    first: Optional[list[Made]] = None
    try:
        pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=multiprocessing.get_context("fork")
        )
        futures = [pool.submit(fn, t) for t in tasks]
    except (OSError, BrokenProcessPool) as err:  # no process could start: draw here
        log.warning("figures drawn in one process: %s", err)
        futures = []
        pool = None
    if pool is not None:
        with pool:  # a figure's own error (in fn) propagates from result(), as it would here
            first = meanwhile()
            for i, future in enumerate(futures):
                try:
                    out[i] = future.result()
                except BrokenProcessPool as err:  # a worker died: the rest are drawn here
                    log.warning("figures drawn in one process: %s", err)
                    break
    first = meanwhile() if first is None else first
    return first, [fn(t) if got is None else got for t, got in zip(tasks, out, strict=True)]
