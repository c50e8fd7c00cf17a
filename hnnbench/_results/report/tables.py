"""The leaderboard as text: the family table (one competitor per family, with its best
and tied marks), the twin-agreement table and every model's row, in Markdown, and the
display frames shared with the HTML page."""

from __future__ import annotations

import math
from typing import Optional

import pandas as pd

from hnnbench import _registry as registry
from hnnbench._results import stats
from hnnbench._results.families import Families
from hnnbench._results.leaderboard import (
    direction_header,
    display_frame,
    metric_declarations,
    short_reason,
    text_column,
)
from hnnbench._results.report.inputs import provenance_lines
from hnnbench._results.report.markdown import md_cell, md_code, md_text

__all__ = [
    "TWIN_FLAG",
    "families_markdown",
    "family_display",
    "leaderboard_markdown",
    "md_table",
    "reason_notes",
    "seed_line",
    "twins_display",
    "twins_line",
]

#: Appended to a family's cell where its twins disagree on that metric.
TWIN_FLAG = "≠"
#: Beside a standing-still cell that no family's leader beats (marks ``unbeaten``).
UNBEATEN_FLAG = "(no family beats it)"
#: The display columns of a family row before its metrics.
FAMILY_IDS = ("system", "family", "seeds_from")


def md_table(frame: pd.DataFrame) -> str:
    """``frame`` as a GitHub Markdown table, every header and cell escaped
    (:func:`hnnbench._results.report.markdown.md_cell`), each metric column's header marked with
    the direction that is better (:func:`hnnbench._results.leaderboard.direction_header`): the one
    writer of Markdown tables."""
    from tabulate import tabulate

    declared = metric_declarations()
    columns = {
        md_cell(direction_header(c, declared)): [md_cell(v) for v in frame[c]]
        for c in frame.columns
    }
    return tabulate(
        columns, headers="keys", tablefmt="github", showindex=False, disable_numparse=True
    )


def _seed_counts(board: pd.DataFrame) -> tuple[str, str]:
    seeds = sorted(
        {s for v in board["seeds"].astype(str) for s in v.split(";") if s not in ("", "nan")},
        key=lambda s: (len(s), s),
    )
    n = board["n_seeds"].astype(int)
    counts = f"{n.min()}" if n.min() == n.max() else f"{n.min()}–{n.max()}"
    return counts, ", ".join(seeds)


def seed_line(board: pd.DataFrame) -> str:
    """What the rows and cells of ``board`` (a leaderboard or a family board) are."""
    profiles = ", ".join(md_code(p) for p in dict.fromkeys(board["profile"].astype(str))) or "?"
    counts, seeds = _seed_counts(board) if not board.empty else ("0", "")
    return (
        f"Profile {profiles}; {counts} seed(s) per row (seeds {seeds}). Cells: "
        f"{stats.cell_rule()}, over the `ok` runs of a pair (its `diverged` runs if "
        "none is ok; `inf` = rollout diverged; `—` = no value or not applicable; "
        "`reason` says why a run was skipped, failed, timed out or diverged). "
        "`cpu_s`: CPU seconds per job, mean over seeds (`—` for records made before "
        "hnnbench recorded it; wall times are in the CSV)."
    )


def family_display(fams: Families) -> tuple[pd.DataFrame, dict[tuple[int, str], str]]:
    """The family table's display frame (twin flags applied) and its marks
    ``{(row, metric): "best" | "tied"}``."""
    board = fams.board.reset_index(drop=True)
    shown = display_frame(board, ids=FAMILY_IDS)
    marks: dict[tuple[int, str], str] = {}
    declared = metric_declarations()
    for metric in [c[: -len("_mark")] for c in board.columns if c.endswith("_mark")]:
        if metric not in shown.columns:
            continue
        for i, mark in enumerate(text_column(board, f"{metric}_mark")):
            if mark in ("best", "tied", "unbeaten"):
                marks[(i, metric)] = mark
        if f"{metric}_effect" in board and metric in declared:
            for i, value in enumerate(pd.to_numeric(board[f"{metric}_effect"], errors="coerce")):
                if not math.isnan(value):
                    marks[(i, f"{metric}:effect")] = effect_text(value, declared[metric].scale)
    if "twins_disagree" in board:
        for i, flagged in enumerate(text_column(board, "twins_disagree")):
            for metric in flagged.split(";"):
                if metric in shown.columns:
                    shown.at[i, metric] = f"{shown.at[i, metric]} {TWIN_FLAG}"
    if "twins" in board:
        shown["twins"] = [short_reason(t, 90) or "—" for t in board["twins"].fillna("")]
    return shown, marks


def reason_notes(shown: pd.DataFrame) -> tuple[pd.DataFrame, list[tuple[int, str]]]:
    """``shown`` (a display frame) without its ``reason`` column, which is empty on most
    rows: a row with a reason gets its note's number after its status (``3 ok, 2
    diverged [1]``; rows of one reason share its number); returns the frame and the
    notes ``[(number, reason), ...]``."""
    if "reason" not in shown:
        return shown, []
    out = shown.drop(columns="reason").reset_index(drop=True)
    numbers: dict[str, int] = {}
    for i, reason in enumerate(text_column(shown, "reason")):
        if reason.strip() in ("", "—", "nan"):
            continue
        number = numbers.setdefault(reason, len(numbers) + 1)
        out.at[i, "status"] = f"{out.at[i, 'status']} [{number}]"
    return out, [(number, reason) for reason, number in numbers.items()]


def twins_display(fams: Families) -> pd.DataFrame:
    """The twin-agreement table for display: one row per (family row, other twin)."""
    twins = fams.twins
    if twins.empty:
        return pd.DataFrame()
    rows = []
    for _, r in twins.iterrows():
        agree = r["agree"]
        rows.append(
            {
                "system": r["system"],
                "family": r["family"],
                **({"variant": r["variant"]} if twins["variant"].fillna("").ne("").any() else {}),
                "seeds from": r["model"],
                "twin": r["twin"],
                "shared seeds": str(r["shared_seeds"]).replace(";", ", ") or "—",
                "agree": "—" if agree is None or pd.isna(agree) else ("yes" if agree else "no"),
                "difference": short_reason(r["difference"], 120) or "—",
            }
        )
    return pd.DataFrame(rows)


def effect_text(value: float, scale: str) -> str:
    """A leader's median paired effect over the runner-up in words: ``×12`` (a log10
    ratio, as a factor) or ``+0.31`` (a difference), ``×inf`` where the runner-up
    diverged on most seeds."""
    if scale == "log":
        if math.isinf(value):
            return "×inf" if value > 0 else "×0"
        factor = 10.0**value
        return f"×{factor:.2g}" if factor < 100 else f"×{factor:.1e}"
    return f"{value:+.2g}"


def _bold(shown: pd.DataFrame, marks: dict[tuple[int, str], str]) -> pd.DataFrame:
    out = shown.copy()
    effects = {key: text for key, text in marks.items() if key[1].endswith(":effect")}
    marks = {key: mark for key, mark in marks.items() if key not in effects}
    for (row, metric), mark in marks.items():
        text = str(out.at[row, metric])
        flag = ""
        if text.endswith(f" {TWIN_FLAG}"):
            text, flag = text[: -len(TWIN_FLAG) - 1], f" {TWIN_FLAG}"
        if mark == "unbeaten":  # the standing-still cell no family's leader beats
            out.at[row, metric] = f"{text} {UNBEATEN_FLAG}{flag}"
            continue
        wrap = "**" if mark == "best" else "*"
        effect = effects.get((row, f"{metric}:effect"))
        out.at[row, metric] = f"{wrap}{text}{wrap}{' ' + effect if effect else ''}{flag}"
    return out


def twins_line(fams: Families) -> str:
    """One line: how many twin pairs agree."""
    twins = fams.twins
    if twins.empty:
        return "No family has twins here."
    known = twins[twins["agree"].notna()]
    agree = int(known["agree"].astype(bool).sum())
    return (
        f"Twins agree on {agree} of {len(known)} (system, family) pairs: the same status "
        "and every metric within its declared tolerance (the factor `hnnbench check "
        f"--rerun` allows, both directions) on every shared seed; `{TWIN_FLAG}` marks a "
        "cell whose metric the twins disagree on."
    )


def families_markdown(fams: Families) -> str:
    """The family table with its marks (Markdown), and below it the notes its status
    cells point to (why runs were skipped, failed, timed out or diverged:
    :func:`reason_notes`)."""
    shown, marks = family_display(fams)
    shown, notes = reason_notes(shown)
    table = md_table(_bold(shown, marks))
    if not notes:
        return table
    return "\n".join(
        [
            table,
            "",
            "Why runs did not finish `ok` ([n] after a status):",
            "",
            *(f"{n}. {md_text(reason)}" for n, reason in notes),
        ]
    )


def reversal_note(board: pd.DataFrame) -> str:
    """A line naming the systems on the board whose reversibility test starts from
    states outside their training data (``System.reversal_in_distribution`` false),
    or ``""``."""
    if board.empty or "reversibility_error_mean" not in board:
        return ""
    systems = []
    for name in dict.fromkeys(board["system"].astype(str)):
        info = registry.discover("system").get(name)
        if info is not None and info.ok and not getattr(info.cls, "reversal_in_distribution", True):
            systems.append(md_code(name))
    if not systems:
        return ""
    return (
        f"`reversibility_error` on {', '.join(systems)} is out of distribution: every "
        "training orbit turns one way, so the momentum-flipped states it starts from "
        "were never seen (a diagnostic, never ranked; docs/METRICS.md)."
    )


def leaderboard_markdown(
    board: pd.DataFrame,
    fams: Families,
    prov: Optional[dict[str, list[str]]] = None,
    figures: tuple[str, ...] = (),
) -> str:
    """leaderboard.md: the family table (first: the README embeds it), the heatmaps,
    the twin agreement, and every model's row."""
    lines = ["# Leaderboard", "", seed_line(fams.board if not fams.board.empty else board), ""]
    if prov is not None:
        lines += [*provenance_lines(prov), ""]
    lines += [
        "## Families",
        "",
        "One row per family: its primary twin's seeds (`seeds_from`: the twin with "
        "the most seeds); the other twins are a parity check. " + stats.best_rule(),
        "",
        families_markdown(fams),
    ]
    note = reversal_note(board)
    if note:
        lines += ["", note]
    for figure in figures:
        lines += ["", f"![{md_cell(figure)}](figures/{md_cell(figure)}.png)"]
    lines += ["", "## Twin agreement", "", twins_line(fams), ""]
    twins = twins_display(fams)
    if not twins.empty:
        lines.append(md_table(twins))
        lines.append("")
    lines += [
        "## Every model",
        "",
        "Both twins of every family, unmarked: the verdicts are the families'.",
        "",
        md_table(display_frame(board)),
        "",
        "Machine-readable: `leaderboard.csv` (every model), `families.csv` (marks "
        "and p-values), `twins.csv`, `aggregate.csv`, `improvement.csv`. Built by "
        "`hnnbench report` from the run records; do not edit by hand.",
        "",
    ]
    return "\n".join(lines)
