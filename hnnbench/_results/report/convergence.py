"""How the tuned track's studies converged (docs/TUNING.md, "Has the criterion
flattened?"): each study's best criterion so far against the CPU seconds it had spent,
trial by trial, read from the study summaries that ``hnnbench tune`` writes
(``tuning/<system>/<model>[.fold<k>].json``, :data:`SUMMARY_FIELDS` and
:data:`TRIAL_FIELDS` checked before use). Two readings per study:
:func:`convergence_table` says what the second half of its trials added (near ×1 the
criterion had flattened within the budget), and what the family had reached when it
had spent the CPU of its system's cheapest whole study (equal compute);
:func:`convergence_figure` draws the curves."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Optional

import pandas as pd

from hnnbench._contracts.errors import DataError
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._record.codec import decode_number
from hnnbench._record.store import parse_file
from hnnbench._record.tracks import study_summary_name
from hnnbench._results.leaderboard import metric_declarations, text_column
from hnnbench._results.report.style import log_axes, model_color, panel_grid, save_panels
from hnnbench._results.report.tables import md_table

__all__ = [
    "CONVERGENCE_COLUMNS",
    "SUMMARY_FIELDS",
    "TRIAL_FIELDS",
    "convergence_figure",
    "convergence_frame",
    "convergence_markdown",
    "convergence_table",
    "field_problem",
    "protocol_reruns",
    "read_study_summaries",
    "studies_convergence",
    "summary_problem",
    "trial0_frame",
]

_NONE = type(None)
#: The fields of a study summary this module reads, with the JSON types each may hold.
SUMMARY_FIELDS: dict[str, tuple[type, ...]] = {
    "profile": (str,),
    "system": (str,),
    "model": (str,),
    "fold": (int, _NONE),
    "steps": (int,),
    "seeds_per_trial": (int,),
    "trial_seeds": (list,),
    "trials": (list,),
}
#: The fields of each of a summary's ``trials`` this module reads (a trial's ``value``
#: is its criterion, the mean over its seeds; ``None`` until it completes, ``"inf"``
#: where a seed diverged: the codec's spelling of a non-finite float; ``last_step``,
#: the step of its last criterion reported, where a pruned trial stopped; ``None``
#: before its first report).
TRIAL_FIELDS: dict[str, tuple[type, ...]] = {
    "number": (int,),
    "state": (str,),
    "value": (float, int, str, _NONE),
    "cpu_s": (float, int),
    "last_step": (int, _NONE),
    "protocol": (bool,),
    "seed_values": (list, _NONE),
}

#: The columns of :func:`convergence_table`.
CONVERGENCE_COLUMNS = (
    "system",
    "model",
    "fold",
    "trials",
    "cpu_s",
    "steps_spent",
    "cap_used",
    "best",
    "best_trial",
    "best_at_half",
    "second_half_gain",
    "equal_cpu_s",
    "best_at_equal_cpu",
    "protocol_seeds",
    "protocol_apart",
)

#: Trial 0 and a protocol record of the same settings and seed agree within this factor
#: where nothing but the process differs (the same code on the same class of CPU).
SAME_RUN = 1.0001


def field_problem(data: Mapping[str, Any], fields: Mapping[str, tuple[type, ...]]) -> str | None:
    """The first field of ``fields`` that ``data`` lacks (a field that may be ``null``
    must still be there) or holds with another JSON type (a bool is not an int unless
    declared), in one line; ``None`` if none."""
    for key, kinds in fields.items():
        if key not in data:
            return f"{key}: missing ({' or '.join(k.__name__ for k in kinds)} expected)"
        value = data[key]
        if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
            return f"{key}: {value!r} is not {' or '.join(k.__name__ for k in kinds)}"
    return None


def summary_problem(summary: Any) -> str | None:
    """Why ``summary`` (a parsed study summary) cannot be read here, or ``None``: an
    object with each field of :data:`SUMMARY_FIELDS`, its fold ``None`` or >= 0, each
    trial of :data:`TRIAL_FIELDS` (a value in words only as the codec spells a
    non-finite float), trial numbers once each and CPU seconds finite and >= 0."""
    if not isinstance(summary, Mapping):
        return "not a JSON object"
    problem = field_problem(summary, SUMMARY_FIELDS)
    if problem:
        return problem
    seeds = summary["trial_seeds"]
    if not all(type(s) is int and s >= 0 for s in seeds):
        return f"trial_seeds: {seeds!r} is not a list of seeds (integers >= 0)"
    if summary["fold"] is not None and summary["fold"] < 0:
        return f"fold: {summary['fold']} is not a fold number (0 or more)"
    for key in ("steps", "seeds_per_trial"):
        if summary[key] < 1:
            return f"{key}: {summary[key]} is not a count (1 or more)"
    numbers = set()
    for trial in summary["trials"]:
        if not isinstance(trial, Mapping):
            return "trials: each must be an object"
        problem = field_problem(trial, TRIAL_FIELDS)
        if problem:
            return f"trial {trial.get('number')!r}: {problem}"
        if isinstance(decode_number(trial["value"]), str):
            return f"trial {trial['number']}: value: {trial['value']!r} is not a number"
        if not (math.isfinite(trial["cpu_s"]) and trial["cpu_s"] >= 0):
            return f"trial {trial['number']}: cpu_s {trial['cpu_s']!r} is not a finite number >= 0"
        if trial["last_step"] is not None and not 0 <= trial["last_step"] <= summary["steps"]:
            step, steps = trial["last_step"], summary["steps"]
            return f"trial {trial['number']}: last_step {step} is not within 0-{steps}"
        values = trial["seed_values"]
        if values is not None and (
            len(values) != len(seeds)
            or not all(isinstance(decode_number(v), (int, float)) for v in values)
        ):
            return f"trial {trial['number']}: seed_values {values!r} are not a number per seed"
        if trial["number"] in numbers:
            return f"trial {trial['number']} is given twice"
        numbers.add(trial["number"])
    return None


def read_study_summaries(folders: Path | Sequence[Path]) -> list[dict[str, Any]]:
    """Every study summary in ``folders`` (``<system>/<model>[.fold<k>].json``: the
    ``tuning/`` folder of ``hnnbench tune``'s ``out=``, one per study of
    scripts/maintainer/tune_sweep.sh, or results/tuning), each checked
    (:func:`summary_problem`), filed under its own system and named for its model and
    fold, each study once across the folders; in the folders' order, sorted by path
    within each. One that is not is :class:`DataError` naming the file and what was
    wrong."""
    found = []
    seen: dict[tuple[str, str, Optional[int]], Path] = {}
    given = [folders] if isinstance(folders, Path) else list(folders)
    for path in (p for folder in given for p in sorted(folder.glob("*/*.json"))):
        data = parse_file(path)
        problem = data if isinstance(data, str) else summary_problem(data)
        if problem is None and isinstance(data, dict):
            key = (data["system"], data["model"], data["fold"])
            name = study_summary_name(data["model"], data["fold"])
            if data["system"] != path.parent.name:
                problem = f"it is a study of {data['system']}, filed under {path.parent.name}"
            elif path.name != name:
                problem = f"it is the study {name}, filed as {path.name}"
            elif key in seen:
                problem = f"the same study as {seen[key]}"
            seen[key] = path
        if problem:
            raise DataError(
                f"{path}: {problem}; expected a study summary written by `hnnbench tune` "
                "(docs/TUNING.md); rerun or remove that study"
            )
        assert isinstance(data, dict)
        found.append(data)
    return found


def _lower_is_better() -> bool:
    """The direction of the criterion, from the metric declared to select on."""
    selecting = [m for m in metric_declarations().values() if m.selects]
    return not selecting or selecting[0].better == "lower"


def convergence_frame(summaries: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """One row per trial of each (checked) study summary, in trial order: ``system``,
    ``model``, ``fold``, ``trial``, ``state``, ``cpu_s`` (the study's CPU seconds
    through this trial, pruned trials included) and ``best`` (the best criterion of its
    complete trials so far; NaN before the first completes), ``steps`` (the optimiser
    steps its trials had trained through this one, over all their seeds: each trial's
    last reported step times the seeds per trial) and ``cap`` (the budget's steps so
    far: the protocol's steps times the seeds per trial, per trial)."""
    lower = _lower_is_better()
    rows = []
    for summary in summaries:
        spent, best, steps, cap = 0.0, math.nan, 0, 0
        per_trial = int(summary["steps"]) * int(summary["seeds_per_trial"])
        for trial in sorted(summary["trials"], key=lambda t: t["number"]):
            spent += float(trial["cpu_s"])
            steps += int(trial["last_step"] or 0) * int(summary["seeds_per_trial"])
            cap += per_trial
            value = float(decode_number(trial["value"]))
            if trial["state"] == "complete" and math.isfinite(value):
                if math.isnan(best) or (value < best if lower else value > best):
                    best = float(value)
            rows.append(
                {"system": summary["system"], "model": summary["model"], "fold": summary["fold"],
                 "trial": trial["number"], "state": trial["state"], "cpu_s": spent, "best": best,
                 "steps": steps, "cap": cap}
            )  # fmt: skip
    return pd.DataFrame(
        rows,
        columns=["system", "model", "fold", "trial", "state", "cpu_s", "best", "steps", "cap"],
    )


def _best_at(curve: pd.DataFrame, cpu_s: float) -> float:
    """The best criterion so far once ``cpu_s`` CPU seconds were spent (NaN if no trial
    had completed by then)."""
    reached = curve[curve["cpu_s"] <= cpu_s * (1 + 1e-9)]
    return float(reached["best"].iloc[-1]) if len(reached) else math.nan


def trial0_frame(summaries: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """The protocol trial (trial 0: the protocol's settings) of each (checked) study
    summary, a row per trial seed: ``profile``, ``system``, ``model``, ``fold``,
    ``seed`` and ``value``, its criterion on that seed (none where the trial has no
    per-seed values)."""
    rows = [
        {"profile": summary["profile"], "system": summary["system"], "model": summary["model"],
         "fold": summary["fold"], "seed": seed, "value": float(decode_number(value))}
        for summary in summaries
        for trial in summary["trials"]
        if trial["protocol"] and trial["seed_values"] is not None
        for seed, value in zip(summary["trial_seeds"], trial["seed_values"], strict=True)
    ]  # fmt: skip
    return pd.DataFrame(rows, columns=["profile", "system", "model", "fold", "seed", "value"])


def protocol_reruns(trial0: pd.DataFrame, runs: pd.DataFrame) -> pd.DataFrame:
    """Trial 0 of each study against the protocol track's records of its model on the
    same seeds (``runs``: the families' records frame, its ``criterion_value`` the
    criterion at the scored checkpoint): one row per study with ``protocol_seeds``, the
    seeds both have, and ``protocol_apart``, the largest factor between the two values
    on one of them (1: the same; NaN without a shared seed, as on a measured system,
    whose trial seeds have no protocol record). Trial 0 re-runs the protocol's
    settings, so beyond :data:`SAME_RUN` the two runs' processes differed (code, class
    of CPU, seeds trained in one batch)."""
    keys = ["profile", "system", "model", "seed"]
    columns = ["system", "model", "fold", "protocol_seeds", "protocol_apart"]
    if trial0.empty or runs.empty or "criterion_value" not in runs:
        return pd.DataFrame(columns=columns)
    protocol = runs.assign(track=text_column(runs, "track", DEFAULT_TRACK))
    protocol = protocol[
        (protocol["track"] == DEFAULT_TRACK) & (text_column(protocol, "variant") == "")
    ]
    theirs = protocol[keys].assign(
        protocol=pd.to_numeric(protocol["criterion_value"], errors="coerce")
    )
    both = trial0.merge(theirs.drop_duplicates(keys), on=keys, how="left")
    both = both.assign(fold=both["fold"].map(lambda v: -1 if v is None or pd.isna(v) else int(v)))
    rows = []
    for (system, model, fold), group in both.groupby(["system", "model", "fold"], sort=False):
        pairs = group[(group["value"] > 0) & (group["protocol"] > 0)]
        apart = (pairs["value"] / pairs["protocol"]).map(lambda r: max(r, 1 / r))
        rows.append(
            {"system": system, "model": model, "fold": fold, "protocol_seeds": len(pairs),
             "protocol_apart": float(apart.max()) if len(pairs) else math.nan}
        )  # fmt: skip
    return pd.DataFrame(rows, columns=columns)


def convergence_table(frame: pd.DataFrame, reruns: Optional[pd.DataFrame] = None) -> pd.DataFrame:
    """One row per study of :func:`convergence_frame`: its trials, CPU seconds and best
    criterion; ``steps_spent``, the optimiser steps its trials trained (over their
    seeds), and ``cap_used``, their fraction of the budget's trials x steps x seeds
    (pruning stops trials early: the budget is a cap); ``best_trial``, the number
    (Optuna's) of the trial that set it; ``best_at_half``, the best after
    the first half of its trials (by number); ``second_half_gain``, what the second
    half added as a factor (best_at_half / best for a lower-is-better criterion; ×1:
    nothing); ``equal_cpu_s``, the CPU of the cheapest whole study of the same system
    and fold among those with a completed trial (a study whose every trial failed, a
    model the system skips, sets none); ``best_at_equal_cpu``, the best this study had
    reached at that CPU; ``protocol_seeds`` and ``protocol_apart``, its trial 0 against
    the protocol records of its seeds (:func:`protocol_reruns`; 0 and NaN without
    ``reruns``). A study with no completed trial has NaN and no best trial."""
    lower = _lower_is_better()
    if frame.empty:
        return pd.DataFrame(columns=list(CONVERGENCE_COLUMNS))
    frame = frame.assign(
        fold=frame["fold"].map(lambda v: -1 if v is None or pd.isna(v) else int(v))
    )
    keys = ["system", "fold", "model"]
    rerun = {
        (r["system"], r["model"], int(r["fold"])): {
            "protocol_seeds": int(r["protocol_seeds"]),
            "protocol_apart": float(r["protocol_apart"]),
        }
        for _, r in (reruns if reruns is not None else pd.DataFrame()).iterrows()
    }
    finished = frame.groupby(keys, sort=False)["best"].last().notna()
    totals = frame.groupby(keys, sort=False)["cpu_s"].max()[finished]
    rows = []
    for (system, fold, model), curve in frame.groupby(keys, sort=False):
        curve = curve.sort_values("trial")
        best = float(curve["best"].iloc[-1])
        setter = curve[curve["best"] == best]["trial"]
        at_half = float(curve["best"].iloc[math.ceil(len(curve) / 2) - 1])
        cheapest = min(
            (v for (s, f, _), v in totals.items() if s == system and f == fold),
            default=math.nan,
        )
        rows.append(
            {
                "system": system,
                "model": model,
                "fold": None if fold == -1 else fold,
                "trials": len(curve),
                "cpu_s": float(curve["cpu_s"].iloc[-1]),
                "steps_spent": int(curve["steps"].iloc[-1]),
                "cap_used": float(curve["steps"].iloc[-1] / curve["cap"].iloc[-1]),
                "best": best,
                "best_trial": int(setter.iloc[0]) if len(setter) else None,
                "best_at_half": at_half,
                "second_half_gain": (at_half / best if lower else best / at_half)
                if best > 0 and at_half > 0  # NaN compares False: no completed trial
                else math.nan,
                "equal_cpu_s": float(cheapest),
                "best_at_equal_cpu": _best_at(curve, float(cheapest)),
                **rerun.get(
                    (system, model, fold), {"protocol_seeds": 0, "protocol_apart": math.nan}
                ),
            }
        )
    table = pd.DataFrame(rows, columns=list(CONVERGENCE_COLUMNS))
    return table.astype({"fold": "Int64", "best_trial": "Int64"})


def studies_convergence(summaries: Sequence[Mapping[str, Any]], runs: pd.DataFrame) -> pd.DataFrame:
    """The section's table of (checked) study summaries: :func:`convergence_table` of
    their curves, with each study's trial 0 read against the protocol track's ``runs``
    (the families' records frame; :func:`protocol_reruns`)."""
    reruns = protocol_reruns(trial0_frame(summaries), runs)
    return convergence_table(convergence_frame(summaries), reruns)


def convergence_figure(frame: pd.DataFrame, path: Path) -> Optional[Path]:
    """Each study's best criterion so far (a step line; a measured system's fold
    studies as thin lines of their family's colour) against the CPU seconds it had
    spent, a panel per system, the CPU of its cheapest whole study with a completed
    trial dotted (one line per fold on a measured system);
    written to ``path`` (``None``, and ``path`` removed, without a completed trial)."""
    frame = frame[frame["best"].notna() & frame["cpu_s"].gt(0)]
    if frame.empty:
        path.unlink(missing_ok=True)
        return None
    panels = list(frame.groupby("system", sort=False))
    fig, axes = panel_grid(len(panels))
    colours = {m: model_color(m) for m in dict.fromkeys(frame["model"].astype(str))}
    for ax, (system, group) in zip(axes, panels, strict=False):
        studies = list(group.groupby(["model", "fold"], sort=False, dropna=False))
        folded = group["fold"].notna().any()
        labelled: set[str] = set()
        for (model, _), curve in studies:
            name = str(model)
            ax.step(
                curve["cpu_s"], curve["best"], where="post", color=colours[name],
                linewidth=0.8 if folded else 1.4, label=None if name in labelled else name,
            )  # fmt: skip
            labelled.add(name)
        for _, fold in group.groupby(group["fold"].fillna(-1), sort=False):
            cheapest = fold.groupby("model")["cpu_s"].max().min()  # each fold's own
            ax.axvline(cheapest, color="0.5", linestyle=":", linewidth=1)
        log_axes(ax)
        ax.set_title(str(system), fontsize=9)
        ax.set_xlabel("tuning CPU s spent (trials so far)", fontsize=8)
        ax.set_ylabel("best criterion so far", fontsize=8)
        ax.legend(fontsize=6)
    return save_panels(fig, axes, len(panels), path)


def convergence_markdown(table: pd.DataFrame) -> str:
    """:func:`convergence_table` as the tracks page's section "Has the criterion
    flattened?": what it reads, a sentence (how many studies set their best in the
    first half of their trials) and a Markdown table; ``""`` without studies."""
    if table.empty:
        return ""

    def study(r: Mapping[str, Any]) -> str:
        fold = "" if pd.isna(r["fold"]) else f" fold {int(r['fold'])}"
        return f"{r['system']}/{r['model']}{fold}"

    gains = table["second_half_gain"]
    read = table[gains.notna()]
    late = read[read["second_half_gain"] > 1]
    early = len(read) - len(late)
    sentence = (
        f"{early} of {len(read)} studies had their best criterion by the end of the first "
        "half of their trials; "
        + (
            "in "
            + ", ".join(
                f"{study(r)} (×{r['second_half_gain']:.2g}, trial {int(r['best_trial'])})"
                for _, r in late.iterrows()
            )
            + " the second half still improved it"
            if len(late)
            else "no second half improved on the first"
        )
        + "."
    )
    paired = table[table["protocol_seeds"].gt(0) & table["protocol_apart"].notna()]
    if len(paired):
        apart = paired[paired["protocol_apart"] > SAME_RUN]
        sentence += (
            f" Trial 0 trains the protocol's settings on the trial seeds: against the "
            f"protocol records of those seeds, {len(paired) - len(apart)} of {len(paired)} "
            f"studies agree within ×{SAME_RUN:g} on every seed"
            + (
                "; "
                + ", ".join(f"{study(r)} ×{r['protocol_apart']:.6g}" for _, r in apart.iterrows())
                + " differ (the two runs' processes differed: code, class of CPU or seeds "
                "trained in one batch, as their records say)"
                if len(apart)
                else ""
            )
            + "."
        )
    unread = table[gains.isna()]
    if len(unread):
        sentence += (
            " No completed trial (or no finite criterion): "
            + ", ".join(study(r) for _, r in unread.iterrows())
            + "."
        )
    lines = [
        "## Has the criterion flattened?",
        "",
        "Each study's best criterion so far, trial by trial, read from its summary "
        "(figures/tuning_convergence.png draws it against the CPU the study had spent): "
        "the best after the first half of its trials against its best (up to 20 "
        "trials, the first half is the protocol's settings and TPE's random start-up "
        "draws, so the second half's gain is what TPE's guided trials added), and at the "
        f"CPU of its system's cheapest whole study, what equal compute would have given. "
        f"{sentence} At the CPU of its system's cheapest whole study (equal compute), a "
        "study whose first trial had not ended has no value (—). `steps spent` counts "
        "the optimiser steps its trials trained over their seeds (a pruned trial's to "
        "where it stopped), `of cap` their fraction of the budget's trials x steps x "
        "seeds: the budget is a cap, which pruning leaves partly unspent. `best trial "
        "no.` is Optuna's trial number (an interrupted trial keeps its number and is "
        "not counted, so numbers can run past the count of trials).",
        "",
    ]

    def num(v: Any, fmt: str) -> str:
        if v is None or pd.isna(v):
            return "—"
        return format(int(v) if fmt.endswith("d") else float(v), fmt)

    shown = pd.DataFrame(
        {
            "system": table["system"],
            "model": table["model"],
            "fold": table["fold"].map(lambda v: num(v, "d")),
            "trials": table["trials"],
            "CPU s": table["cpu_s"].map(lambda v: num(v, ",.0f")),
            "steps spent": table["steps_spent"].map(lambda v: num(v, ",d")),
            "of cap": table["cap_used"].map(lambda v: num(v, ".0%")),
            "best": table["best"].map(lambda v: num(v, ".3g")),
            "best trial no.": table["best_trial"].map(lambda v: num(v, "d")),
            "after half": table["best_at_half"].map(lambda v: num(v, ".3g")),
            "second half ×": table["second_half_gain"].map(lambda v: num(v, ".2f")),
            "equal CPU s": table["equal_cpu_s"].map(lambda v: num(v, ",.0f")),
            "best at equal CPU": table["best_at_equal_cpu"].map(lambda v: num(v, ".3g")),
            "trial 0 / protocol ×": table["protocol_apart"].map(lambda v: num(v, ".6g")),
        }
    )
    if shown["fold"].eq("—").all():
        shown = shown.drop(columns=["fold"])
    return "\n".join([*lines, ""]) + md_table(shown)
