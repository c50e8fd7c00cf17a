"""The verdicts of a report: the family view (:mod:`hnnbench._results.families`) and the
aggregate across systems (:mod:`hnnbench._results.aggregate`), built once and rendered as
Markdown: the aggregate table, and which verdicts its intervals support."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import pandas as pd

from hnnbench._contracts.names import DEFAULT_TRACK, STANDING_STILL, TRACKS
from hnnbench._results import stats
from hnnbench._results.aggregate import Aggregate, aggregate, headline_metrics
from hnnbench._results.families import RANKING_KEY, SCOPE_KEY, Families, families, scope_name
from hnnbench._results.leaderboard import (
    flag_column,
    metric_declarations,
    records_frame,
    text_column,
)
from hnnbench._results.report.markdown import md_code, md_text
from hnnbench._results.report.tables import effect_text, md_table

__all__ = [
    "Verdicts",
    "aggregate_frame",
    "aggregate_markdown",
    "build_verdicts",
    "findings_lines",
    "left_out_lines",
    "main_key",
    "main_scope",
    "marks_line",
    "order_lines",
    "rank_frame",
    "rank_left_out_lines",
    "scope_label",
    "scope_line",
    "scopes",
    "supported_lines",
    "tracks_frame",
    "tracks_markdown",
    "tuning_costs",
]

#: The tracks table's column of the standing-still reference's mean (the zero-field
#: reference: a model that predicts no motion).
STILL_COLUMN = "still_mean"


@dataclass
class Verdicts:
    """A report's family view and aggregate."""

    families: Families
    aggregate: Aggregate = field(default_factory=Aggregate)

    @property
    def main(self) -> Optional[Scope]:
        """The scope every part of the report speaks of (:func:`main_key` of the family
        board; of the aggregate where the board is empty)."""
        key = main_key(self.families.board)
        return key if key is not None else main_key(self.aggregate.iqm)


def build_verdicts(
    records: list[dict],
    board: pd.DataFrame,
    with_aggregate: bool = True,
    variants: Optional[list[str]] = None,
) -> Verdicts:
    """The family view of ``records`` (whose leaderboard is ``board``) and, unless
    ``with_aggregate`` is false, its aggregate across systems."""
    frame = records_frame(records, variants)
    fams = families(frame, board)
    return Verdicts(fams, aggregate(fams) if with_aggregate else Aggregate(note="not built"))


def _fmt(x: float) -> str:
    if x is None or pd.isna(x):
        return "—"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    text = f"{x:.2f}"
    return "0.00" if text == "-0.00" else text


def _interval(point: float, low: float, high: float) -> str:
    if pd.isna(point):
        return "—"
    if pd.isna(low) or pd.isna(high):
        return _fmt(point)
    return f"{_fmt(point)} [{_fmt(low)}, {_fmt(high)}]"


Scope = tuple[str, ...]


def _scope_values(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame``'s :data:`~hnnbench._results.families.SCOPE_KEY` columns as strings (a missing
    column or value is ``""``; a missing track is the protocol)."""
    out = pd.DataFrame(index=frame.index)
    for k in SCOPE_KEY:
        out[k] = text_column(frame, k, DEFAULT_TRACK if k == "track" else "")
    if "track" in out:
        out.loc[out["track"] == "", "track"] = DEFAULT_TRACK
    return out


def main_key(frame: pd.DataFrame) -> Optional[Scope]:
    """The main scope's key in ``frame`` (a family board, an aggregate frame): the paper
    profile where there is one, and in it the protocol track where there is one, else
    the first scope's; ``None`` for an empty frame."""
    if frame.empty:
        return None
    values = _scope_values(frame)
    if (values["profile"] == "paper").any():
        values = values[values["profile"] == "paper"]
    if (values["track"] == DEFAULT_TRACK).any():
        values = values[values["track"] == DEFAULT_TRACK]
    return tuple(values.iloc[0])


def main_scope(frame: pd.DataFrame, key: Optional[Scope] = None) -> pd.DataFrame:
    """The rows of one scope (:data:`hnnbench._results.families.SCOPE_KEY`) of a frame with
    scope columns: those of ``key`` (:attr:`Verdicts.main`: the scope every part of a
    report speaks of; possibly none), else :func:`main_key`'s. The README's aggregate,
    its per-system marks, the heatmaps and the performance profiles speak of the main
    scope; the other tracks are compared with it in the tracks table."""
    if frame.empty:
        return frame
    key = main_key(frame) if key is None else key
    values = _scope_values(frame)
    return frame[(values == pd.Series(key, index=list(SCOPE_KEY))).all(axis=1)]


def scopes(frame: pd.DataFrame, key: Optional[Scope] = None) -> list[tuple[bool, pd.DataFrame]]:
    """``(is_main, rows)`` per scope of ``frame`` present in it, the main scope
    (:func:`main_scope` of ``key``) first."""
    if frame.empty:
        return []
    values = _scope_values(frame)
    key = main_key(frame) if key is None else key
    out = []
    for scope, rows in frame.groupby([values[k] for k in SCOPE_KEY], sort=False):
        scope = scope if isinstance(scope, tuple) else (scope,)
        out.append((tuple(map(str, scope)) == tuple(key or ()), rows))
    return sorted(out, key=lambda item: not item[0])


def scope_label(frame: pd.DataFrame) -> str:
    """``paper``, ``paper/tuned``: the scope of ``frame``'s first row (the track left
    out where it is the protocol), as the aggregate names its performance profiles."""
    if frame.empty:
        return ""
    return scope_name(tuple(_scope_values(frame).iloc[0]))


def rank_frame(
    agg: Aggregate, metrics: Optional[list[str]] = None, key: Optional[Scope] = None
) -> pd.DataFrame:
    """The headline across systems, free of any normalisation: one row per family, its
    mean rank [interval] of each of ``metrics`` (default: the headline metrics that have
    one) over the systems every family ran, in the main scope (:func:`main_scope`)."""
    ranks = main_scope(agg.ranks, key)
    if ranks.empty:
        return pd.DataFrame()
    if metrics is None:
        metrics = [m for m in headline_metrics() if (ranks["metric"] == m).any()]
    rows = []
    for family in dict.fromkeys(ranks["family"]):
        row: dict[str, str] = {"family": str(family)}
        for metric in metrics:
            sel = ranks[(ranks["family"] == family) & (ranks["metric"] == metric)]
            if sel.empty:
                row[f"{metric} rank"] = "—"
                continue
            r = sel.iloc[0]
            row[f"{metric} rank"] = (
                f"{_interval(r['mean_rank'], r['rank_low'], r['rank_high'])}"
                f" (of {int(r['n_families'])}, {int(r['n_systems'])} sys)"
            )
        rows.append(row)
    frame = pd.DataFrame(rows)
    first = f"{metrics[0]} rank" if metrics else None
    if first is not None and first in frame:
        order = main_scope(agg.ranks, key)
        order = order[order["metric"] == metrics[0]].set_index("family")["mean_rank"]
        frame = (
            frame.assign(_r=[order.get(f, math.inf) for f in frame["family"]])
            .sort_values("_r", kind="stable")
            .drop(columns="_r")
        )
    return frame.reset_index(drop=True)


def rank_left_out_lines(agg: Aggregate, key: Optional[Scope] = None) -> list[str]:
    """One line per headline metric whose mean rank leaves systems out (some family did
    not run them): which."""
    ranks = main_scope(agg.ranks, key)
    lines = []
    for metric in [m for m in headline_metrics() if (ranks["metric"] == m).any()]:
        left = text_column(ranks[ranks["metric"] == metric], "left_out").iloc[0]
        if left:
            names = ", ".join(md_text(x) for x in left.split(";"))
            lines.append(
                f"The {md_code(metric)} ranks leave out {names}: not every family "
                "ran there (pairs that both ran them count in P(A > B))."
            )
    return lines


def order_lines(agg: Aggregate, key: Optional[Scope] = None) -> list[str]:
    """How the secondary view's order (IQM of normalised scores) moves under a second
    floor, per metric of the main scope."""
    label = scope_label(main_scope(agg.ranks if not agg.ranks.empty else agg.iqm, key))
    lines = []
    for (scope, metric), (main, alt) in agg.orders.items():
        if scope != label or metric not in headline_metrics():
            continue
        moves = [
            f"{md_text(f)} {main.index(f) + 1} -> {alt.index(f) + 1}"
            for f in main
            if f in alt and main.index(f) != alt.index(f)
        ]
        said = ", ".join(moves) if moves else "no family moves"
        lines.append(
            f"{md_code(metric)}: with the floor at half the best family's mean on "
            f"each system instead, the IQM order is {', '.join(map(md_text, alt))} "
            f"({said})."
        )
    return lines


def aggregate_frame(
    agg: Aggregate, metrics: Optional[list[str]] = None, key: Optional[Scope] = None
) -> pd.DataFrame:
    """One row per family: the IQM [interval] of each of ``metrics`` (default: the
    headline metrics that have an aggregate) and the systems each covers, in the main
    scope (:func:`main_scope`)."""
    iqm = main_scope(agg.iqm, key)
    if iqm.empty:
        return pd.DataFrame()
    if metrics is None:
        metrics = [m for m in headline_metrics() if (iqm["metric"] == m).any()]
    rows = []
    for family in dict.fromkeys(iqm["family"]):
        row: dict[str, str] = {"family": str(family)}
        for metric in metrics:
            sel = iqm[(iqm["family"] == family) & (iqm["metric"] == metric)]
            if sel.empty:
                row[f"{metric} IQM"] = "—"
                continue
            r = sel.iloc[0]
            row[f"{metric} IQM"] = (
                f"{_interval(r['iqm'], r['iqm_low'], r['iqm_high'])} ({int(r['n_systems'])} sys)"
            )
        rows.append(row)
    return pd.DataFrame(rows)


def supported_lines(
    agg: Aggregate, metrics: Optional[list[str]] = None, key: Optional[Scope] = None
) -> list[str]:
    """Markdown bullets: per metric, which family beats which with the interval of P(A > B)
    above one half, and which pairs no interval separates (the main scope)."""
    poi = main_scope(agg.improvement, key)
    if poi.empty:
        return []
    iqm_all = main_scope(agg.iqm, main_key(poi))
    order = list(dict.fromkeys(iqm_all.sort_values("iqm", ascending=False)["family"]))
    if metrics is None:
        metrics = [m for m in headline_metrics() if (poi["metric"] == m).any()]
    lines = []
    for metric in metrics:
        sel = poi[poi["metric"] == metric]
        iqm = iqm_all[iqm_all["metric"] == metric]
        ranked = list(iqm.sort_values("iqm", ascending=False)["family"]) or order
        if "claimable" in sel and not flag_column(sel, "claimable", False).any():
            fewest = int(pd.to_numeric(sel["min_seeds"], errors="coerce").min())
            lines.append(
                f"- {md_code(metric)}: too few seeds to separate (as few as "
                f"{fewest} per system; a claim needs "
                f"{stats.MIN_SEPARABLE_SEEDS})."
            )
            continue
        if "claimable" in sel:
            sel = sel[flag_column(sel, "claimable", False)]
        beats = []
        for family in ranked:
            wins = sel[(sel["family"] == family) & (sel["p_low"] > 0.5)]
            if not wins.empty:
                others = [o for o in ranked if o in set(wins["other"])]
                beats.append(f"{md_text(family)} beats {', '.join(map(md_text, others))}")
        open_pairs = sel[(sel["p_low"] <= 0.5) & (sel["p_high"] >= 0.5)]
        seen, ties = set(), []
        for _, r in open_pairs.iterrows():
            pair = frozenset((str(r["family"]), str(r["other"])))
            if pair not in seen:
                seen.add(pair)
                ties.append(f"{md_text(r['family'])}–{md_text(r['other'])}")
        text = "; ".join(beats) if beats else "no family beats another"
        tail = f". Not separated: {', '.join(ties)}" if ties else ""
        lines.append(f"- {md_code(metric)}: {text} (95% interval of P(A > B) above 0.5){tail}.")
    return lines


def marks_line(
    fams: Families, metrics: Optional[list[str]] = None, key: Optional[Scope] = None
) -> str:
    """How many (system, metric) cells have a separated best, of those with a leader
    (the main scope: :func:`main_scope`)."""
    board = main_scope(fams.board, key)
    if metrics is None:
        metrics = [m for m in headline_metrics() if f"{m}_mark" in board]
    board = board[text_column(board, "variant") == ""]
    best = tied = unbeaten = 0
    for metric in metrics:
        if f"{metric}_mark" not in board:
            continue
        for _, group in board.groupby([k for k in RANKING_KEY if k != "variant"], sort=False):
            marks = set(text_column(group, f"{metric}_mark"))
            best += "best" in marks
            tied += "tied" in marks and "best" not in marks
            unbeaten += "unbeaten" in marks
    n = best + tied
    seeds = int(pd.to_numeric(board["n_seeds"], errors="coerce").min()) if len(board) else 0
    tail = ""
    if seeds < stats.MIN_SEPARABLE_SEEDS:
        tail = (
            f" Rows rest on as few as {seeds} seed(s): too few seeds to separate "
            f"(the two-sided sign test needs {stats.MIN_SEPARABLE_SEEDS} shared seeds "
            f"between two families, {stats.min_separable_seeds(comparisons=5)} among six; "
            f"its smallest p with {seeds} is {min(1.0, 2 * 0.5**seeds):.3g})."
        )
    names = ", ".join(md_code(m) for m in metrics)
    still = (
        f" In {unbeaten} more, no family beats standing still (nothing marked)." if unbeaten else ""
    )
    return (
        f"Per system ({names}): {best} of {n} cells with a leader have a separated "
        f"best (bold); in {tied} the leaders are tied (italics).{still}{tail}"
    )


def findings_lines(fams: Families, key: Optional[Scope] = None) -> list[str]:
    """One bullet per system with a separated best (the main scope): each best family and
    its median paired effect over the runner-up [interval], metrics declared on the same
    evidence (:attr:`hnnbench.Metric.evidence`: the rollout metrics) that agree counted
    as one finding."""
    board = main_scope(fams.board, key)
    if board.empty:
        return []
    board = board[text_column(board, "variant") == ""]
    declared = metric_declarations()
    metrics = [
        m[: -len("_mark")]
        for m in board.columns
        if m.endswith("_mark") and m[: -len("_mark")] in declared
    ]
    lines = []
    for system, group in board.groupby("system", sort=False):
        said: dict[tuple[str, str], list[str]] = {}
        for metric in metrics:
            best = group[text_column(group, f"{metric}_mark") == "best"]
            if best.empty:
                continue
            r = best.iloc[0]
            decl = declared[metric]
            effect = ""
            if f"{metric}_effect" in r and not pd.isna(r[f"{metric}_effect"]):
                effect = (
                    f" ({effect_text(r[f'{metric}_effect'], decl.scale)} "
                    f"[{effect_text(r[f'{metric}_effect_low'], decl.scale)}, "
                    f"{effect_text(r[f'{metric}_effect_high'], decl.scale)}] over "
                    f"{md_text(r[f'{metric}_effect_vs'])})"
                )
            group_key = (str(r["family"]), decl.evidence or metric)
            said.setdefault(group_key, []).append(f"{md_code(metric)}{effect}")
        if not said:
            continue
        parts = []
        for (family, evidence), items in said.items():
            joint = (
                " and ".join(items)
                if len(items) < 3
                else ", ".join(items[:-1]) + f" and {items[-1]}"
            )
            one = f" (one {evidence} finding)" if len(items) > 1 else ""
            parts.append(f"{md_text(family)} on {joint}{one}")
        lines.append(f"- {md_code(str(system))}: best: " + "; ".join(parts) + ".")
    return lines


def left_out_lines(agg: Aggregate, key: Optional[Scope] = None) -> list[str]:
    """One line per (headline metric, reason): the systems its aggregate leaves out (the
    main scope: :func:`main_scope`)."""
    scales = main_scope(agg.scales, key)
    if scales.empty:
        return []
    unused = scales[~scales["used"].astype(bool) & scales["metric"].isin(headline_metrics())]
    lines = []
    for (metric, why), group in unused.groupby(["metric", "why_not"], sort=False):
        systems = ", ".join(map(md_text, group["system"]))
        lines.append(f"Left out of {md_code(metric)}: {systems} ({md_text(why)}).")
    return lines


def aggregate_markdown(
    verdicts: Verdicts, figure: Optional[str] = None, heading: str = "# Across systems"
) -> str:
    """The aggregate across systems (aggregate.md; the README's aggregate block): the
    method, the IQM table, the verdicts its intervals support, the per-system marks,
    and ``figure`` (a path to the performance-profile figure) if given."""
    agg, key = verdicts.aggregate, verdicts.main
    lines = [heading, ""] if heading else []
    scope = scope_line(verdicts)
    if scope:
        lines += [scope, ""]
    ranks = rank_frame(agg, key=key) if not agg.ranks.empty else pd.DataFrame()
    table = aggregate_frame(agg, key=key) if not agg.iqm.empty else pd.DataFrame()
    if ranks.empty and table.empty:
        why = agg.note if agg.empty else "no (system, metric) of this scope is normalised"
        lines += [f"No aggregate: {md_text(why or 'nothing to aggregate')}.", ""]
        lines += [*left_out_lines(agg, key)] + [""] * bool(left_out_lines(agg, key))
        lines += [marks_line(verdicts.families, key=key), ""]
        return "\n".join(lines)
    if not ranks.empty:
        lines += [stats.rank_rule(), "", md_table(ranks), ""]
        lines += [*rank_left_out_lines(agg, key)] + [""] * bool(rank_left_out_lines(agg, key))
    lines += [
        "What the intervals support:",
        "",
        *supported_lines(agg, key=key),
        f"- {marks_line(verdicts.families, key=key)}",
        "",
    ]
    found = findings_lines(verdicts.families, key)
    if found:
        lines += [
            "Separated bests per system, with the leader's median paired effect over "
            "the runner-up [interval] (×: a factor on a log-scale metric, +: a "
            "difference):",
            "",
            *found,
            "",
        ]
    if not table.empty:
        lines += [
            "A second view, which depends on a choice of scale: "
            + stats.aggregate_rule(md_text(agg.baseline or "the baseline")),
            "",
            md_table(table),
            "",
        ]
        moves = order_lines(agg, key)
        if moves:
            lines += ["How its order hangs on the floor: " + " ".join(moves), ""]
    left = left_out_lines(agg, key)
    if left:
        lines += [*left, ""]
    if figure:
        lines += [f"![Performance profiles]({figure})", ""]
    return "\n".join(lines)


def scope_line(verdicts: Verdicts) -> str:
    """Which rows the aggregate and the marks speak of, where the report holds several
    scopes (profiles or tracks); ``""`` where it holds one."""
    board = verdicts.families.board
    if board.empty or len(scopes(board)) < 2:
        return ""
    label = scope_label(main_scope(board, verdicts.main))
    return (
        f"Of the {md_code(label)} rows (profile/track; the other tracks are set beside "
        "it in the tracks table, tracks.md)."
    )


# --------------------------------------------------------------------------- tracks


def _leaders(rows: pd.DataFrame, metric: str) -> str:
    """One track's verdict on one (system, metric): ``best: <family>``, ``tied: <a>,
    <b>`` (the leader and every family not separated from it, the best mean first), or
    ``""`` (no leader:
    fewer than two ranked families with every seed ``ok``, or the track did not run)."""
    column = f"{metric}_mark"
    if column not in rows:
        return ""
    marks = text_column(rows, column)
    if (marks == "unbeaten").any():
        return "no family beats standing still"
    best = rows.loc[marks == "best", "family"].astype(str).tolist()
    if best:
        return f"best: {best[0]}"
    few = (marks == "too_few_seeds").any()
    tied_rows = (
        rows[marks == "tied"]
        if not few
        else rows[
            pd.to_numeric(rows.get(f"{metric}_mean"), errors="coerce").notna()
            & flag_column(rows, "ranked", True)
        ]
    )
    mean = f"{metric}_mean"
    if mean in tied_rows and len(tied_rows):  # the best mean first
        declared = metric_declarations().get(metric)
        higher = declared is not None and declared.better == "higher"
        tied_rows = tied_rows.assign(_m=pd.to_numeric(tied_rows[mean], errors="coerce"))
        tied_rows = tied_rows.sort_values("_m", ascending=not higher, kind="stable")
    tied = tied_rows["family"].astype(str).tolist()
    if few:  # no outcome of so few seeds could separate: every family, best mean first
        return f"too few seeds to separate: {', '.join(tied)}"
    return f"tied: {', '.join(tied)}" if tied else ""


def _main_rows_by_track(board: pd.DataFrame) -> pd.DataFrame:
    """A family board's rows of no variant, its ``track`` column filled (a row with none
    is of :data:`DEFAULT_TRACK`) and text."""
    board = board[text_column(board, "variant") == ""]
    return board.assign(track=text_column(board, "track", DEFAULT_TRACK))


def tracks_frame(fams: Families, metrics: Optional[list[str]] = None) -> pd.DataFrame:
    """The verdicts of every track side by side (docs/TUNING.md): one row per (profile,
    system, metric of ``metrics``, default the headline ones) where some track other
    than the protocol has family rows; ``still_mean``: the standing-still
    reference's mean (the first track that has one; ``""`` where none ran); a column per
    track present (its :func:`_leaders` text) and ``<track>_effect``: its leader's paired
    effect over the runner-up with its interval (the families table's ``<metric>_effect``,
    ``""`` where the track names no single leader's effect); ``changes``: whether two
    tracks with a verdict name leaders that have no family in common (``best: lnn``
    against ``tied: dhnn, lnn`` is no change: the second track does not separate its
    leaders, the LNN among them), and ``mean_changes``: whether the family with the best
    mean (the first named) differs, a statement about means. Empty when every row is of
    the protocol track."""
    board = fams.board
    if board.empty or "track" not in board:
        return pd.DataFrame()
    board = _main_rows_by_track(board)
    present = [t for t in TRACKS if t in set(board["track"])]
    present += sorted(set(board["track"]) - set(present))
    if present == [DEFAULT_TRACK]:
        return pd.DataFrame()
    if metrics is None:
        metrics = [m for m in headline_metrics() if f"{m}_mark" in board]
    rows = []
    for (profile, system), group in board.groupby(["profile", "system"], sort=False):
        if set(group["track"]) == {DEFAULT_TRACK}:
            continue
        for metric in metrics:
            verdicts = {t: _leaders(group[group["track"] == t], metric) for t in present}
            effects = {f"{t}_effect": _effect(group[group["track"] == t], metric) for t in present}
            said = [v for v in verdicts.values() if ": " in v]  # those naming families
            leaders = [_leader_set(v) for v in said]
            changes = any(not (a & b) for i, a in enumerate(leaders) for b in leaders[i + 1 :])
            firsts = {v.partition(": ")[2].split(",")[0].strip() for v in said}
            rows.append(
                {
                    "profile": profile,
                    "system": system,
                    "metric": metric,
                    STILL_COLUMN: _standing_still_text(group, metric),
                    **verdicts,
                    **effects,
                    "changes": changes,
                    "mean_changes": len(firsts) > 1,
                }
            )
    return pd.DataFrame(rows)


def _standing_still_text(rows: pd.DataFrame, metric: str) -> str:
    """The standing-still reference's mean of ``metric`` among ``rows`` (the first
    track's that has one), formatted; ``""`` where no standing-still row has one."""
    column = f"{metric}_mean"
    if "reference" not in rows or column not in rows:
        return ""
    still = rows[text_column(rows, "reference") == STANDING_STILL]
    values = pd.to_numeric(still[column], errors="coerce").dropna()
    return f"{float(values.iloc[0]):.2g}" if len(values) else ""  # 1.9e-23 is not 0.00


def _effect(rows: pd.DataFrame, metric: str) -> str:
    """A track's leader's paired effect over its runner-up on ``metric``, with its
    interval (``×12 [×3, ×40] vs mlp``); ``""`` where none was computed."""
    column = f"{metric}_effect"
    if column not in rows:
        return ""
    decl = metric_declarations().get(metric)
    scale = decl.scale if decl is not None else "log"
    for _, r in rows.iterrows():
        value = pd.to_numeric(pd.Series([r[column]]), errors="coerce").iloc[0]
        if pd.isna(value):
            continue
        low, high = r.get(f"{column}_low", math.nan), r.get(f"{column}_high", math.nan)
        against = r.get(f"{column}_vs", "")
        return (
            f"{effect_text(float(value), scale)} [{effect_text(float(low), scale)}, "
            f"{effect_text(float(high), scale)}]" + (f" vs {against}" if against else "")
        )
    return ""


def _leader_set(verdict: str) -> set[str]:
    """The families a :func:`_leaders` text names (``best: a`` -> {a}; ``tied: a, b``)."""
    return {name.strip() for name in verdict.partition(": ")[2].split(",") if name.strip()}


def tuning_costs(fams: Families) -> pd.DataFrame:
    """What each family's tuned settings cost: one row per (profile, system) with tuned
    family rows, a column per family (in the board's order) holding the CPU seconds of
    the studies of its primary twin, the one its family row shows (``tuning_cpu_s``:
    every trial, pruned ones included, not the final seeds; summed over a measured
    system's fold studies), formatted; ``—`` where the family
    has no tuned row there. Empty when no row is of the tuned track."""
    board = fams.board
    if board.empty or "track" not in board or "tuning_cpu_s" not in board:
        return pd.DataFrame()
    board = _main_rows_by_track(board)
    ranked = flag_column(board, "ranked", True)
    tuned = board[(board["track"] == "tuned") & ranked]  # the references are not tuned
    if tuned.empty:
        return pd.DataFrame()
    order = list(dict.fromkeys(tuned["family"].astype(str)))
    rows = []
    for (profile, system), group in tuned.groupby(["profile", "system"], sort=False):
        cpu = dict(
            zip(
                group["family"].astype(str),
                pd.to_numeric(group["tuning_cpu_s"], errors="coerce"),
                strict=True,
            )
        )
        rows.append(
            {
                "profile": profile,
                "system": system,
                **{
                    f: ("—" if f not in cpu or not math.isfinite(cpu[f]) else f"{cpu[f]:,.0f}")
                    for f in order
                },
            }
        )
    return pd.DataFrame(rows)


def _verdict_lines(frame: pd.DataFrame) -> list[str]:
    """The tracks table (a non-empty :func:`tracks_frame`), its legend, and the lines
    naming where a verdict, or only the best mean, changes between tracks."""
    lines = [md_table(frame.drop(columns=["changes", "mean_changes"]).replace("", "—")), ""]
    tracks = [
        c
        for c in frame.columns
        if c not in ("profile", "system", "metric", "changes", "mean_changes", STILL_COLUMN)
        and not c.endswith("_effect")
    ]
    lines += [
        "Each cell names the best family, or the families tied for the lead with the "
        "best mean first; `<track>_effect` is that track's leader's paired effect over "
        "its runner-up by mean (the family after it, whether or not the verdict "
        "separates them) with its own interval, not adjusted for the verdict's other "
        "comparisons (docs/STATISTICS.md), and `still_mean` the "
        "standing-still reference's mean, the value a model that predicts no motion "
        "scores. On `energy_mse` only the families whose rollout beats standing still "
        "(`rollout_skill` above 0) are contested, since standing still conserves a "
        "conservative system's energy exactly: its leaders there score above "
        "`still_mean`. A verdict changes between two tracks where their leaders "
        "have no family in common (a cell of too few seeds names every family with a "
        "value, so no "
        f"verdict can change against it). A track of fewer than "
        f"{stats.MIN_SEPARABLE_SEEDS} seeds never separates its leaders, and one of fewer than "
        f"{stats.min_separable_seeds(comparisons=5)} never separates one of six families "
        f'from the other five ("too few '
        "seeds to separate\": the two-sided sign test with Holm's correction, "
        "docs/STATISTICS.md), and the recipe track ranks only the families that "
        "declare a recipe. The tuned track reads the final seeds no trial of the "
        "family's study trained (seeds 2 to 9 where the trials trained seeds 0 and 1): "
        "a trial seed's final run is the selected trial again, chosen for its score on "
        "that seed (docs/TUNING.md).",
        "",
    ]

    def said(r: pd.Series) -> str:
        return "; ".join(f"{t} {md_text(str(r[t]))}" for t in tracks if r[t])

    def best_means(r: pd.Series) -> str:
        named = [(t, str(r[t]).partition(": ")) for t in tracks if ": " in str(r[t])]
        return "; ".join(
            f"{t} {md_text(rest.split(',')[0].strip())} ({md_text(kind)})"
            for t, (kind, _, rest) in named
        )

    changed = frame[frame["changes"]]
    if changed.empty:
        lines += ["No verdict changes between tracks on any system and headline metric shown.", ""]
    else:
        lines += ["Where the verdict changes between tracks:", ""]
        lines += [
            f"- {md_code(str(r['system']))}, {md_code(str(r['metric']))}: {said(r)}."
            for _, r in changed.iterrows()
        ]
        lines.append("")
    means = frame[frame["mean_changes"] & ~frame["changes"]]
    if not means.empty:
        lines += [
            "Where only the best mean moves to another family (not separated; a "
            "difference of means over the seeds, not a verdict), each track's family "
            "with the best mean, and its cell's verdict:",
            "",
        ]
        lines += [
            f"- {md_code(str(r['system']))}, {md_code(str(r['metric']))}: {best_means(r)}."
            for _, r in means.iterrows()
        ]
        lines.append("")
    return lines


def tracks_markdown(
    frame: pd.DataFrame, costs: Optional[pd.DataFrame] = None, tuning: str = ""
) -> str:
    """The tracks side by side (:func:`tracks_frame`) and one line per (system, metric)
    whose verdict changes between tracks; a line saying so when no other track ran; then,
    where ``costs`` (:func:`tuning_costs`) has rows, what each family's tuning cost; then
    ``tuning`` (the tuning gain and the studies,
    :func:`hnnbench._results.report.tuning.gain_markdown`)."""
    if frame.empty and (costs is None or costs.empty) and not tuning:
        return (
            "Only the protocol track has published rows: no tuned or recipe rows yet "
            "(docs/TUNING.md)."
        )
    lines = [] if frame.empty else _verdict_lines(frame)
    if costs is not None and not costs.empty:
        lines += [
            "What each family's tuned settings cost: the CPU seconds of its studies "
            "(one per fold on a measured system; every trial, pruned ones included, the "
            "final seeds not counted), the "
            "leaderboard's `tuning_cpu_s`. `hnnbench tune` gives every family of a "
            "system the same trials of the same steps, and `hnnbench check` flags a "
            "system whose tuned records state unequal budgets (docs/TUNING.md).",
            "",
            md_table(costs),
            "",
        ]
    if tuning:
        lines += [tuning, ""]
    return "\n".join(lines).rstrip("\n")
