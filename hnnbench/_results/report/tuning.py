"""The tuned track's own tables and figures (docs/TUNING.md): what each study was and
cost (:func:`studies_frame`), the tuning gain per family and system, tuned against the
protocol on the final seeds, paired by seed (:func:`tuning_gain`), which families it
helped and hurt (:func:`gain_summary`, drawn by :func:`gain_figure`), and each family's
best criterion against the CPU its studies spent (:func:`cost_figure`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Optional

import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter

from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._record.tracks import track_of
from hnnbench._results import stats
from hnnbench._results.aggregate import headline_metrics
from hnnbench._results.families import Families
from hnnbench._results.leaderboard import flag_column, metric_declarations, text_column
from hnnbench._results.report.style import family_color, log_axes, panel_grid, save_panels
from hnnbench._results.report.tables import effect_text, md_table

__all__ = [
    "CRITERION_ROW",
    "GAIN_SIDES",
    "STUDY_COLUMNS",
    "TRIAL",
    "UNSEEN",
    "cost_figure",
    "gain_figure",
    "gain_markdown",
    "gain_summary",
    "studies_frame",
    "tuning_gain",
]

#: The columns of :func:`studies_frame`.
STUDY_COLUMNS = (
    "profile",
    "system",
    "family",
    "model",
    "fold",
    "criterion",
    "seeds_per_trial",
    "trials",
    "completed",
    "steps",
    "budget",
    "cpu_s",
    "cpu_s_per_trial",
    "best",
    "protocol",
)


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def studies_frame(recs: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """One row per study of the tuned records (a model's study on a system, one per
    fold on a measured system): its criterion, seeds per trial, trials, steps, the
    declared budget (trials x steps x seeds per trial), how many trials ran to the end
    (``completed``: the candidates its selection chose from; the rest were pruned), its
    CPU seconds (in all and per trial), the selected trial's criterion (``best``) and
    the protocol trial's (``protocol``). Empty without tuned records."""
    rows: dict[tuple[Any, ...], dict[str, Any]] = {}
    for rec in recs:
        tuning = rec.get("tuning")
        if track_of(rec) != "tuned" or not isinstance(tuning, Mapping):
            continue
        if "selected" not in tuning:  # a trial's own record
            continue
        seeds = tuning.get("seeds_per_trial", 1)
        trials, steps = tuning.get("trials"), tuning.get("steps")
        key = (
            rec.get("profile"),
            rec.get("system"),
            rec.get("model"),
            tuning.get("study"),
        )
        rows[key] = {
            "profile": rec.get("profile"),
            "system": rec.get("system"),
            "family": rec.get("family") or rec.get("model"),
            "model": rec.get("model"),
            "fold": tuning.get("fold"),
            "criterion": tuning.get("criterion") or tuning.get("objective"),
            "seeds_per_trial": seeds,
            "trials": trials,
            "completed": tuning.get("completed"),
            "steps": steps,
            "budget": f"{trials} x {steps} x {seeds}",
            "cpu_s": _number(tuning.get("cpu_s")),
            "cpu_s_per_trial": _number(tuning.get("cpu_s_per_trial")),
            "best": _number(tuning.get("selected_value")),
            "protocol": _number(tuning.get("protocol_value")),
        }
    return pd.DataFrame(list(rows.values()), columns=list(STUDY_COLUMNS))


#: The tuning gain's row of the criterion the studies selected on, read at each run's
#: scored checkpoint (``selection.validation_loss``).
CRITERION_ROW = "criterion"


def _paired(
    mine: pd.DataFrame, theirs: pd.DataFrame, column: str, better: str, scale: str
) -> Optional[dict[str, Any]]:
    """``column`` of ``mine`` against ``theirs`` (records-frame rows, one per seed) on
    the seeds both ran, paired by seed (:func:`hnnbench._results.stats.paired_effect`,
    ``mine`` as the leader): ``n``, ``gain``, ``low``, ``high``, ``coverage``, ``scale``;
    ``None`` without a shared seed."""
    if column not in mine or column not in theirs:
        return None
    a = dict(zip(mine["seed"], pd.to_numeric(mine[column], errors="coerce"), strict=True))
    b = dict(zip(theirs["seed"], pd.to_numeric(theirs[column], errors="coerce"), strict=True))
    shared = sorted(s for s in set(a) & set(b) if not (pd.isna(a[s]) and pd.isna(b[s])))
    if not shared:
        return None
    gain, low, high, coverage = stats.paired_effect(
        [a[s] for s in shared], [b[s] for s in shared], better, scale
    )
    return {"n": len(shared), "gain": gain, "low": low, "high": high, "coverage": coverage,
            "scale": scale}  # fmt: skip


#: The seeds a tuning gain row reads (its ``seeds`` column): the final seeds no trial of
#: the family's study trained (the table's), or its trial seeds (their final runs are
#: the selected trial again, chosen for its score on them: kept to show that luck).
UNSEEN, TRIAL = "unseen", "trial"
#: Gains closer than this (log10 units, ×1.00023; or the metric's own units on a
#: linear scale) are the same when the trial seeds' and the unseen seeds' are compared.
SAME_GAIN = 1e-4


def _seeds_of(value: Any) -> Optional[str]:
    """What a tuned run's seed is, from ``tuning_trial_seed``: :data:`TRIAL`,
    :data:`UNSEEN`, or ``None`` where its record names no trial seeds (neither)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    return TRIAL if bool(value) else UNSEEN


def tuning_gain(fams: Families, metrics: Optional[Sequence[str]] = None) -> pd.DataFrame:
    """The tuning gain per (profile, system, family, metric of ``metrics``, default
    every ranked one with values, ``seeds``): the tuned track against the protocol
    track, paired by seed (:func:`_paired`, the tuned side as the leader: positive where
    tuning helped, negative where it hurt), with ``n`` paired seeds, the median
    ``gain``, its interval ``low``-``high`` and the interval's ``coverage``; ``scale``:
    ``log`` (a log10 ratio) or ``linear``. ``seeds`` says which seeds a row reads:
    :data:`UNSEEN`, the final seeds no trial of the family's study trained (the gain),
    or :data:`TRIAL`, its trial seeds (a trial seed's final run is the selected trial
    again, whose score on that seed chose it, so its gain carries the selection's luck).
    A tuned run whose record names no trial seeds is in neither. With the default
    metrics, a row :data:`CRITERION_ROW` first: the selection criterion
    (``criterion_value``). Empty without both tracks."""
    runs = (
        pd.concat([fams.runs, fams.in_sample], ignore_index=True)
        if not fams.in_sample.empty
        else fams.runs
    )
    columns = ["profile", "system", "family", "metric", "seeds", "n", "gain", "low", "high",
               "coverage", "scale"]  # fmt: skip
    if runs.empty or "track" not in runs:
        return pd.DataFrame(columns=columns)
    runs = runs.assign(track=text_column(runs, "track", DEFAULT_TRACK))
    runs = runs[text_column(runs, "variant") == ""]
    runs = runs[flag_column(runs, "ranked", True)]
    declared = metric_declarations()
    wanted = [(CRITERION_ROW, "criterion_value", "lower", "log")] if metrics is None else []
    for metric in (
        [m for m in declared if declared[m].ranked and m in runs] if metrics is None else metrics
    ):
        decl = declared.get(metric)
        if decl is not None:
            wanted.append((metric, metric, decl.better, decl.scale))
    order = list(dict.fromkeys(fams.board["family"].astype(str))) if "family" in fams.board else []
    order += [f for f in dict.fromkeys(runs["family"].astype(str)) if f not in order]
    rows = []
    for (profile, system), group in runs.groupby(["profile", "system"], sort=False):
        tuned, protocol = group[group["track"] == "tuned"], group[group["track"] == DEFAULT_TRACK]
        if tuned.empty or protocol.empty:
            continue
        which = tuned["tuning_trial_seed"].map(_seeds_of) if "tuning_trial_seed" in tuned else None
        for seeds in (UNSEEN, TRIAL):
            part = tuned[which == seeds] if which is not None else tuned.iloc[:0]
            for family in [f for f in order if f in set(part["family"].astype(str))]:
                a = part[part["family"].astype(str) == family]
                b = protocol[protocol["family"].astype(str) == family]
                where = {"profile": profile, "system": system, "family": family}
                for name, column, better, scale in wanted:
                    pair = _paired(a, b, column, better, scale)
                    if pair is not None:
                        rows.append({**where, "metric": name, "seeds": seeds, **pair})
    return pd.DataFrame(rows, columns=columns)


def _trial_seeds_sentence(gain: pd.DataFrame) -> str:
    """How the gain on the trial seeds compares with the unseen seeds', per metric: in
    how many of the studies with both (finite) it was larger, and smaller, by more than
    :data:`SAME_GAIN`; ``""`` without any."""
    if "seeds" not in gain:
        return ""
    keys = ["profile", "system", "family", "metric"]
    both = gain[gain["seeds"] == TRIAL].merge(
        gain[gain["seeds"] == UNSEEN], on=keys, suffixes=("_trial", "_unseen")
    )
    diff = pd.to_numeric(both["gain_trial"], errors="coerce") - pd.to_numeric(
        both["gain_unseen"], errors="coerce"
    )
    both = both[diff.notna() & diff.map(math.isfinite)]
    if both.empty:
        return ""
    counts = ", ".join(
        f"`{m}` {int((d > SAME_GAIN).sum())} larger and {int((d < -SAME_GAIN).sum())} "
        f"smaller of {len(d)}"
        for m, d in diff.loc[both.index].groupby(both["metric"], sort=False)
    )
    return (
        " On the trial seeds themselves (not shown; `seeds` = `trial` in tuning_gain.csv) "
        f"the gain was, against the unseen seeds': {counts} studies (the rest the same). "
        "A selection's own seeds are no fair test of it whichever way they fell (the "
        "protocol's run on a seed varies too), so the table leaves them out."
    )


#: The columns of :func:`gain_summary` that name families: where the gain's interval lies
#: wholly above no change (tuning helped), holds it (the seeds cannot tell), or lies
#: wholly below it (tuning hurt).
GAIN_SIDES = ("helped", "within noise", "hurt")


def _side(row: Mapping[str, Any]) -> str:
    """Which of :data:`GAIN_SIDES` a tuning gain row is on: its interval against 0 (the
    log ratio or difference of no change), read only where it can separate, from at
    least :data:`~hnnbench._results.stats.MIN_SEPARABLE_SEEDS` paired seeds at the
    stated confidence (fewer: ``within noise``, however the seeds fell)."""
    low, high = float(row["low"]), float(row["high"])
    n, coverage = int(row["n"]), float(row["coverage"])
    if n < stats.MIN_SEPARABLE_SEEDS or not coverage >= stats.CONFIDENCE:
        return GAIN_SIDES[1]
    return GAIN_SIDES[0] if low > 0 else GAIN_SIDES[2] if high < 0 else GAIN_SIDES[1]


def _near_one(row: Mapping[str, Any]) -> str:
    """A gain as :func:`effect_text` writes it, with three digits within 10 % of no
    change (a gain of ×1.04 whose interval clears ×1 is not written ×1)."""
    value, scale = float(row["gain"]), str(row["scale"])
    if scale == "log" and abs(value) < math.log10(1.1):
        return f"×{10.0**value:.3g}"
    return effect_text(value, scale)


def _summary_metrics(gain: pd.DataFrame) -> list[str]:
    """The criterion row, then the headline metrics, those ``gain`` has."""
    present = set(gain["metric"].astype(str))
    return [m for m in [CRITERION_ROW, *headline_metrics()] if m in present]


def gain_summary(gain: pd.DataFrame) -> pd.DataFrame:
    """Which families tuning helped and hurt: one row per (profile, system, metric: the
    criterion, then the headline metrics) of :func:`tuning_gain`'s unseen seeds, a
    column per side of :data:`GAIN_SIDES` naming its families with their median gain,
    largest first (``dhnn ×4.7, lnn ×3``; ``—`` where none). Empty without rows."""
    columns = ["profile", "system", "metric", *GAIN_SIDES]
    if gain.empty or "seeds" not in gain:
        return pd.DataFrame(columns=columns)
    gain = gain[gain["seeds"] == UNSEEN]
    metrics = _summary_metrics(gain)
    rows = []
    for (profile, system), group in gain.groupby(["profile", "system"], sort=False):
        for metric in metrics:
            part = group[group["metric"] == metric]
            part = part.assign(_g=pd.to_numeric(part["gain"], errors="coerce"))
            sides: dict[str, list[str]] = {side: [] for side in GAIN_SIDES}
            for _, r in part.sort_values("_g", ascending=False, kind="stable").iterrows():
                sides[_side(r)].append(f"{r['family']} {_near_one(r)}")
            if not part.empty:
                rows.append({"profile": profile, "system": system, "metric": metric,
                             **{s: ", ".join(v) or "—" for s, v in sides.items()}})  # fmt: skip
    return pd.DataFrame(rows, columns=columns)


def _gain_plot(gain: pd.DataFrame) -> Optional[Figure]:
    """:func:`gain_figure`'s figure (``None`` without log-scale unseen rows): one
    ``errorbar`` per (panel, family) drawn, in panel order."""
    if gain.empty or "seeds" not in gain:
        return None
    gain = gain[(gain["seeds"] == UNSEEN) & (gain["scale"] == "log")]
    value = {c: pd.to_numeric(gain[c], errors="coerce") for c in ("gain", "low", "high")}
    gain = gain[value["gain"].abs() < math.inf]  # a median of -inf and +inf (NaN): no point
    metrics = _summary_metrics(gain)
    if gain.empty or not metrics:
        return None
    limits = {}  # per metric, log10: its finite values and no change, with a margin
    for metric in metrics:
        part = gain[gain["metric"] == metric]
        ends = pd.concat([pd.to_numeric(part[c]) for c in ("gain", "low", "high")])
        ends = ends[ends.abs() < math.inf]
        limits[metric] = (min(float(ends.min()), 0.0) - 0.2, max(float(ends.max()), 0.0) + 0.2)
    profiles = list(dict.fromkeys(gain["profile"].astype(str)))
    families = list(dict.fromkeys(gain["family"].astype(str)))
    systems = {p: list(dict.fromkeys(gain[gain["profile"] == p]["system"].astype(str)))
               for p in profiles}  # fmt: skip
    tall = sum(0.5 + 0.16 * len(families) * len(systems[p]) for p in profiles)
    fig = Figure(figsize=(3.6 * len(metrics), tall + 0.9))
    axes = fig.subplots(
        len(profiles), len(metrics), squeeze=False, sharex="col",
        gridspec_kw={"height_ratios": [len(systems[p]) for p in profiles]},
    )  # fmt: skip
    step = 0.8 / max(len(families), 1)
    for i, profile in enumerate(profiles):
        names = systems[profile]
        for j, metric in enumerate(metrics):
            ax = axes[i][j]
            part = gain[(gain["profile"] == profile) & (gain["metric"] == metric)]
            lim = limits[metric]
            for k, family in enumerate(families):
                rows = part[part["family"].astype(str) == family]
                if rows.empty:
                    continue
                colour = family_color(family)
                y = [names.index(str(s)) - 0.4 + step * (k + 0.5) for s in rows["system"]]
                x, lo, hi = (pd.to_numeric(rows[c]).clip(*lim) for c in ("gain", "low", "high"))
                ax.errorbar(10.0**x, y, xerr=[10.0**x - 10.0**lo, 10.0**hi - 10.0**x],
                            fmt="o", ms=3, lw=1, color=colour)  # fmt: skip
                for side, clipped, marker in ((lo, "low", "<"), (hi, "high", ">")):
                    cut = pd.to_numeric(rows[clipped]) != side  # beyond the axis: an arrow
                    ys = [v for v, c in zip(y, cut, strict=True) if c]
                    if ys:
                        ax.scatter(10.0 ** side[cut], ys, marker=marker, s=14, color=colour)
            ax.axvline(1.0, color="black", lw=0.8)
            ax.set_xscale("log")
            ax.set_xlim(10.0 ** lim[0], 10.0 ** lim[1])
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            ax.set_yticks(range(len(names)), names if j == 0 else [""] * len(names), fontsize=7)
            ax.set_ylim(len(names) - 0.5, -0.5)
            for edge in range(len(names) - 1):
                ax.axhline(edge + 0.5, color="0.85", lw=0.6)
            ax.set_title(f"{metric} ({profile})", fontsize=9)
            ax.set_xlabel("tuning gain (×; above 1: tuning helped)", fontsize=7)
            ax.tick_params(axis="x", labelsize=7, labelbottom=True)
    handles = [Line2D([], [], marker="o", ls="", color=family_color(f), label=f) for f in families]
    fig.legend(handles=handles, loc="lower center", ncol=len(families), fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.5 / (tall + 0.9), 1, 1))
    return fig


def gain_figure(gain: pd.DataFrame, path: Path) -> Optional[Path]:
    """The tuning gain on the unseen seeds as intervals, a panel per log-scale metric of
    :func:`gain_summary` (columns) and profile (rows): a row per system, a point per
    family (its median gain: protocol / tuned for a lower-is-better metric, tuned /
    protocol for a higher-is-better one; log x axis, one per metric), its interval as a bar
    (an arrow where it runs past the axis: a diverged side's infinite gain), the line of
    no change at ×1; written to ``path`` (``None``, and ``path`` removed, without such
    rows)."""
    fig = _gain_plot(gain)
    if fig is None:
        path.unlink(missing_ok=True)
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def _gain_text(row: Mapping[str, Any]) -> str:
    scale = str(row["scale"])
    return (
        f"{effect_text(float(row['gain']), scale)} "
        f"[{effect_text(float(row['low']), scale)}, {effect_text(float(row['high']), scale)}]"
        f" ({int(row['n'])})"
    )


def gain_markdown(gain: pd.DataFrame, studies: pd.DataFrame) -> str:
    """The tuning gain as a table (a row per system and metric, a column per family:
    ``×factor [low, high] (seeds)``; above 1 tuning helped, below 1 it hurt), then what
    each study was: its criterion, budget, CPU, and best criterion against the
    protocol trial's. ``gain`` is :func:`tuning_gain`'s frame: the table shows its
    unseen seeds' rows and says how the trial seeds' compare. ``""`` when both are
    empty."""
    lines: list[str] = []
    every = gain
    gain = gain[gain["seeds"] == UNSEEN] if "seeds" in gain else gain
    if not gain.empty:
        families = list(dict.fromkeys(gain["family"].astype(str)))
        rows = []
        for (_, system, metric), group in gain.groupby(["profile", "system", "metric"], sort=False):
            cells = {str(r["family"]): _gain_text(r) for _, r in group.iterrows()}
            rows.append(
                {"system": system, "metric": metric, **{f: cells.get(f, "—") for f in families}}
            )
        lines += [
            "## Tuning gain",
            "",
            "The tuned track against the protocol track, family by family, paired by "
            "seed, on the final seeds no trial of the family's study trained (their number "
            "in brackets: seeds 2 to 9 where the trials trained seeds 0 and 1; a trial "
            "seed's final run is the selected trial again, whose own score chose it): the "
            "median over seeds of protocol / tuned (a lower-is-better metric; tuned / "
            "protocol for a higher-is-better one; a difference on a linear scale), with its "
            "order-statistic interval "
            f"(coverage at least {stats.CONFIDENCE:.0%} from 6 seeds; the whole range "
            "below). Above ×1 (or +) tuning helped; below ×1 (or −) it made the family "
            "worse, although its selection was never worse than the protocol's settings on "
            "the criterion within its study (the protocol's settings are trial 0 of every "
            "study): a winner's curse, or a criterion that does not carry to the metric. "
            f"The row `{CRITERION_ROW}` is the criterion the studies selected on, at each "
            "run's scored checkpoint: near ×1 the selection's margin over the protocol's "
            "settings was its trial seeds' luck, within seed noise." + _trial_seeds_sentence(every),
            "",
            md_table(pd.DataFrame(rows)),
            "",
        ]
        summary = gain_summary(every)
        if not summary.empty:
            folded_here = sorted(
                {str(sy) for sy, f in zip(studies["system"], studies["fold"], strict=True)
                 if pd.notna(f)} & set(summary["system"].astype(str))
            )  # fmt: skip
            lines += [
                "Which families tuning helped, on the criterion and the headline metrics "
                "(the table above, read by its intervals; figures/tuning_gain.png draws "
                "them): a family is under `helped` where its interval lies wholly above ×1 "
                "(above 0 on a linear scale), under `hurt` where it lies wholly below, and "
                "`within noise` where it holds ×1 or reads fewer than "
                f"{stats.MIN_SEPARABLE_SEEDS} paired seeds, each with its median gain, "
                "largest first."
                + (
                    " On "
                    + ", ".join(f"`{sy}`" for sy in folded_here)
                    + " the interval counts seeds that share a fold as independent (below)."
                    if folded_here
                    else ""
                ),
                "",
                md_table(
                    summary
                    if summary["profile"].nunique() > 1
                    else summary.drop(columns=["profile"])
                ),
                "",
            ]
    folded = sorted(
        {str(sy) for sy, f in zip(studies["system"], studies["fold"], strict=True) if pd.notna(f)}
        & set(gain["system"].astype(str))
    )
    if folded and lines:
        lines += [
            "On " + ", ".join(f"`{sy}`" for sy in folded) + " (a measured system: one study "
            "per fold) the seeds of one fold share its data and its study's selected "
            "settings, so its paired seeds are fewer independent draws than their number "
            '(docs/TUNING.md, "Tuning gain").',
            "",
        ]
    gained = {f"{sy}/{fa}" for sy, fa in zip(gain["system"], gain["family"], strict=True)}
    missing = sorted(
        {f"{sy}/{fa}" for sy, fa in zip(studies["system"], studies["family"], strict=True)} - gained
    )
    if missing:
        lines += [] if lines else ["## Tuning gain", ""]
        lines += [
            "No tuning gain for " + ", ".join(missing) + ": none of their final seeds is "
            "both known to be unseen by their study (its record names the trial seeds, "
            "and the seed is not one of them) and paired with a ranked protocol run of the "
            "family.",
            "",
        ]
    if not studies.empty:
        shown = studies.assign(
            fold=studies["fold"].map(lambda v: "—" if v is None or pd.isna(v) else str(int(v))),
            completed=studies["completed"].map(
                lambda v: "—" if v is None or pd.isna(v) else str(int(v))
            ),
            criterion=studies["criterion"].astype(str),
            cpu_s=studies["cpu_s"].map(lambda v: f"{v:,.0f}"),
            cpu_s_per_trial=studies["cpu_s_per_trial"].map(lambda v: f"{v:,.1f}"),
            best=studies["best"].map(lambda v: f"{v:.3g}"),
            protocol=studies["protocol"].map(lambda v: f"{v:.3g}"),
        ).drop(columns=["profile", "model", "trials", "steps", "seeds_per_trial"])
        lines += [
            "## The studies",
            "",
            "Each study's criterion (the system's selection criterion, read on "
            "validation), its budget (trials x steps x seeds per trial: the same for "
            "every family of a system), how many of its trials ran to the end "
            "(`completed`, the protocol's trial among them: the candidates the selection "
            "chose from; the pruner stopped the rest), its CPU seconds (every trial, pruned ones "
            "included; the final seeds not counted) in all and per trial, the selected "
            "trial's criterion and the protocol trial's (the mean over the trial's "
            "seeds). Equal budgets are not equal CPU: figures/tuning_cost.png plots each "
            "family's best criterion against its CPU.",
            "",
            md_table(shown),
            "",
        ]
    return "\n".join(lines).rstrip("\n")


def cost_figure(studies: pd.DataFrame, path: Path) -> Optional[Path]:
    """Each family's best criterion (its selected trial's, summed over a measured
    system's folds as the mean) against the CPU seconds its studies spent, a panel
    per (profile, system), the protocol trial's criterion beside it as an open marker;
    written to ``path`` (``None``, and ``path`` removed, without studies)."""
    finite = pd.to_numeric(studies["best"], errors="coerce").gt(0) & pd.to_numeric(
        studies["cpu_s"], errors="coerce"
    ).gt(0)
    studies = studies[finite]
    if studies.empty:  # records before the criterion (no selected value): nothing to draw
        path.unlink(missing_ok=True)
        return None
    per = (
        studies.groupby(["profile", "system", "family"], sort=False)
        .agg(cpu_s=("cpu_s", "sum"), best=("best", "mean"), protocol=("protocol", "mean"))
        .reset_index()
    )
    panels = list(per.groupby(["profile", "system"], sort=False))
    fig, axes = panel_grid(len(panels))
    for ax, ((profile, system), group) in zip(axes, panels, strict=False):
        for _, r in group.iterrows():
            colour = family_color(str(r["family"]))
            ax.scatter([r["cpu_s"]], [r["best"]], color=colour, label=str(r["family"]))
            if float(r["protocol"]) > 0 and math.isfinite(float(r["protocol"])):
                ax.scatter([r["cpu_s"]], [r["protocol"]], facecolors="none", edgecolors=colour)
        log_axes(ax)
        ax.set_title(f"{system} ({profile})", fontsize=9)
        ax.set_xlabel("tuning CPU s (all trials)", fontsize=8)
        ax.set_ylabel("criterion: selected (filled), protocol (open)", fontsize=7)
        ax.legend(fontsize=6)
    return save_panels(fig, axes, len(panels), path)
