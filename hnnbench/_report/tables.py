"""The leaderboard as text: Markdown and the display frame shared with the HTML page,
with the best value of each system marked."""

from __future__ import annotations

import math
from typing import Optional, cast

import pandas as pd

from hnnbench._report.inputs import provenance_lines
from hnnbench._report.markdown import md_cell, md_code
from hnnbench._table import display_frame, metric_declarations

__all__ = ["best_cells", "leaderboard_markdown", "md_table", "seed_line"]


def md_table(frame: pd.DataFrame) -> str:
    """``frame`` as a GitHub Markdown table, every header and cell escaped
    (:func:`hnnbench._report.markdown.md_cell`): the one writer of Markdown tables."""
    from tabulate import tabulate

    columns = {md_cell(c): [md_cell(v) for v in frame[c]] for c in frame.columns}
    return tabulate(columns, headers="keys", tablefmt="github", showindex=False,
                    disable_numparse=True)


def seed_line(board: pd.DataFrame) -> str:
    profiles = ", ".join(md_code(p) for p in dict.fromkeys(board["profile"].astype(str))) or "?"
    seeds = sorted({s for v in board["seeds"].astype(str) for s in v.split(";") if s != ""},
                   key=lambda s: (len(s), s))
    n = board["n_seeds"].astype(int)
    counts = f"{n.min()}" if n.min() == n.max() else f"{n.min()}–{n.max()}"
    return (f"Profile {profiles}; {counts} seed(s) per pair (seeds {', '.join(seeds)}). "
            "Cells are mean ± std over seeds (std omitted for one seed), over the `ok` runs "
            "of a pair (its `diverged` runs if none is ok; `inf` = rollout diverged; "
            "`—` = no value or not applicable). Bold: the best value of the system among "
            "the trained models whose every seed is `ok` (the oracle is shown, not "
            "ranked; a mean over the surviving seeds of a pair that diverged is not).")


def best_cells(board: pd.DataFrame) -> set[tuple[int, str]]:
    """``{(row position, metric)}`` holding the best finite mean of its (profile, system,
    variant, track) among ranked rows whose every seed is ``ok``, for each ranked metric
    (:attr:`hnnbench.Metric.ranked`), in the metric's declared
    direction and within its declared domain. A pair with a diverged or failed seed is
    averaged over its ``ok`` seeds only, so it would be ranked on its luckier seeds: it
    is never marked best."""
    declared = metric_declarations()
    metrics = [c[:-5] for c in board.columns if c.endswith("_mean") and c[:-5] in declared
               and declared[c[:-5]].ranked]
    out: set[tuple[int, str]] = set()
    board = board.reset_index(drop=True)
    keys = ["profile", "system"] + (["variant"] if "variant" in board else []) \
        + (["track"] if "track" in board else [])  # tracks are never ranked together
    ranked = board["ranked"].fillna(True).astype(bool) if "ranked" in board else \
        pd.Series(True, index=board.index)
    if {"n_ok", "n_seeds"} <= set(board.columns):
        ranked &= board["n_ok"] == board["n_seeds"]
    for _, group in board[ranked].groupby(keys, dropna=False, sort=False):
        for metric in metrics:
            low, high = declared[metric].domain
            values = pd.to_numeric(group[f"{metric}_mean"], errors="coerce")
            # a value outside the metric's declared domain (a negative error, from a
            # record that a strict load refuses) is shown, never marked best
            values = values[values.apply(lambda v, lo=low, hi=high: math.isfinite(v)
                                         and lo <= v <= hi)]
            if len(values) < 2:
                continue
            pick = values.idxmax() if declared[metric].better == "higher" else values.idxmin()
            out.add((int(cast(int, pick)), metric))
    return out


def _marked(board: pd.DataFrame, bold: str = "**") -> pd.DataFrame:
    shown = display_frame(board)
    for row, metric in best_cells(board):
        if metric in shown.columns:
            shown.at[row, metric] = f"{bold}{str(shown.at[row, metric])}{bold}"
    return shown


def leaderboard_markdown(board: pd.DataFrame, prov: Optional[dict[str, list[str]]] = None,
                         figures: tuple[str, ...] = ()) -> str:
    lines = ["# Leaderboard", "", seed_line(board), ""]
    if prov is not None:
        lines += [*provenance_lines(prov), ""]
    lines.append(md_table(_marked(board)))
    for figure in figures:
        lines += ["", f"![{md_cell(figure)}](figures/{md_cell(figure)}.png)"]
    lines += ["", "Machine-readable: `leaderboard.csv`. Built by `hnnbench report` from the "
              "run records; do not edit by hand.", ""]
    return "\n".join(lines)


def marked_display(board: pd.DataFrame) -> tuple[pd.DataFrame, set[tuple[int, str]]]:
    """The display frame and its best cells (for the HTML page)."""
    return display_frame(board), best_cells(board)


