"""The verdicts of a report: the family view (:mod:`hnnbench._families`) and the
aggregate across systems (:mod:`hnnbench._aggregate`), built once and rendered as
Markdown: the aggregate table, and which verdicts its intervals support."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import pandas as pd

from hnnbench import _stats as stats
from hnnbench._aggregate import Aggregate, aggregate, headline_metrics
from hnnbench._families import RANKING_KEY, SCOPE_KEY, Families, families, key_of, select
from hnnbench._record_schema import DEFAULT_TRACK, TRACKS
from hnnbench._report.markdown import md_code, md_text
from hnnbench._report.tables import md_table
from hnnbench._table import records_frame

__all__ = ["Verdicts", "aggregate_frame", "aggregate_markdown", "build_verdicts",
           "left_out_lines", "main_scope", "marks_line", "scope_label", "scopes",
           "supported_lines", "tracks_frame", "tracks_markdown"]


@dataclass
class Verdicts:
    """A report's family view and aggregate."""

    families: Families
    aggregate: Aggregate = field(default_factory=Aggregate)


def build_verdicts(records: list[dict], board: pd.DataFrame, with_aggregate: bool = True,
                   variants: Optional[list[str]] = None) -> Verdicts:
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


def main_scope(frame: pd.DataFrame) -> pd.DataFrame:
    """The rows of one scope (:data:`hnnbench._families.SCOPE_KEY`) of a frame with
    scope columns (an aggregate frame, a family board): the paper profile's where there
    is one, and in it the protocol track's where there is one, else the first scope's.
    The README's aggregate, its per-system marks and the heatmaps speak of this scope;
    the other tracks are compared with it in the tracks table."""
    if frame.empty:
        return frame
    if "profile" in frame and (frame["profile"].astype(str) == "paper").any():
        frame = frame[frame["profile"].astype(str) == "paper"]
    if "track" in frame:
        track = frame["track"].fillna(DEFAULT_TRACK).astype(str)
        if (track == DEFAULT_TRACK).any():
            frame = frame[track == DEFAULT_TRACK]
    return select(frame, SCOPE_KEY, key_of(frame.iloc[0], SCOPE_KEY))


def scopes(frame: pd.DataFrame) -> list[tuple[bool, pd.DataFrame]]:
    """``(is_main, rows)`` per scope (:data:`hnnbench._families.SCOPE_KEY`) of ``frame``,
    the main scope (:func:`main_scope`) first."""
    if frame.empty:
        return []
    main = main_scope(frame)
    out = [(True, main)]
    keys = [k for k in SCOPE_KEY if k in frame]
    for _, rows in frame.groupby([frame[k].fillna("").astype(str) for k in keys],
                                 sort=False):
        if not rows.index.isin(main.index).any():
            out.append((False, rows))
    return out


def scope_label(frame: pd.DataFrame) -> str:
    """``paper``, ``paper/tuned``: the scope of ``frame``'s first row (the track left
    out where it is the protocol), as the aggregate names its performance profiles."""
    if frame.empty:
        return ""
    names = key_of(frame.iloc[0], SCOPE_KEY)
    return "/".join(n for k, n in zip(SCOPE_KEY, names, strict=True)
                    if not (k == "track" and n in ("", DEFAULT_TRACK)))


def aggregate_frame(agg: Aggregate, metrics: Optional[list[str]] = None) -> pd.DataFrame:
    """One row per family: the IQM [interval] of each of ``metrics`` (default: the
    headline metrics that have an aggregate) and the systems each covers, in the main
    scope (:func:`main_scope`)."""
    iqm = main_scope(agg.iqm)
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
            row[f"{metric} IQM"] = (f"{_interval(r['iqm'], r['iqm_low'], r['iqm_high'])} "
                                    f"({int(r['n_systems'])} sys)")
        rows.append(row)
    return pd.DataFrame(rows)


def supported_lines(agg: Aggregate, metrics: Optional[list[str]] = None) -> list[str]:
    """Markdown bullets: per metric, which family beats which with the interval of P(A > B)
    above one half, and which pairs no interval separates (the main scope)."""
    poi = main_scope(agg.improvement)
    if poi.empty:
        return []
    scope = key_of(poi.iloc[0], SCOPE_KEY)
    iqm_all = select(agg.iqm, SCOPE_KEY, scope)
    order = list(dict.fromkeys(iqm_all.sort_values("iqm", ascending=False)["family"]))
    if metrics is None:
        metrics = [m for m in headline_metrics() if (poi["metric"] == m).any()]
    lines = []
    for metric in metrics:
        sel = poi[poi["metric"] == metric]
        iqm = iqm_all[iqm_all["metric"] == metric]
        ranked = list(iqm.sort_values("iqm", ascending=False)["family"]) or order
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
        lines.append(f"- {md_code(metric)}: {text} (95% interval of P(A > B) above "
                     f"0.5){tail}.")
    return lines


def marks_line(fams: Families, metrics: Optional[list[str]] = None) -> str:
    """How many (system, metric) cells have a separated best, of those with a leader
    (the main scope: :func:`main_scope`)."""
    board = main_scope(fams.board)
    if metrics is None:
        metrics = [m for m in headline_metrics() if f"{m}_mark" in board]
    if "variant" in board:
        board = board[board["variant"].fillna("").astype(str) == ""]
    best = tied = 0
    for metric in metrics:
        if f"{metric}_mark" not in board:
            continue
        for _, group in board.groupby([k for k in RANKING_KEY if k != "variant"], sort=False):
            marks = set(group[f"{metric}_mark"].fillna("").astype(str))
            best += "best" in marks
            tied += "tied" in marks and "best" not in marks
    n = best + tied
    seeds = int(pd.to_numeric(board["n_seeds"], errors="coerce").min()) if len(board) else 0
    tail = ""
    if seeds < stats.MIN_SEPARABLE_SEEDS:
        tail = (f" Rows rest on as few as {seeds} seed(s): the sign test needs "
                f"{stats.MIN_SEPARABLE_SEEDS} shared seeds to separate anything "
                f"(its smallest p with {seeds} is {0.5 ** seeds:.3g}).")
    names = ", ".join(md_code(m) for m in metrics)
    return (f"Per system ({names}): {best} of {n} cells with a leader have a separated "
            f"best (bold); in {tied} the leaders are tied (italics).{tail}")


def left_out_lines(agg: Aggregate) -> list[str]:
    """One line per (headline metric, reason): the systems its aggregate leaves out (the
    main scope: :func:`main_scope`)."""
    scales = main_scope(agg.scales)
    if scales.empty:
        return []
    unused = scales[~scales["used"].astype(bool) & scales["metric"].isin(headline_metrics())]
    lines = []
    for (metric, why), group in unused.groupby(["metric", "why_not"], sort=False):
        systems = ", ".join(map(md_text, group["system"]))
        lines.append(f"Left out of {md_code(metric)}: {systems} ({md_text(why)}).")
    return lines


def aggregate_markdown(verdicts: Verdicts, figure: Optional[str] = None,
                       heading: str = "# Across systems") -> str:
    """The aggregate across systems (aggregate.md; the README's aggregate block): the
    method, the IQM table, the verdicts its intervals support, the per-system marks,
    and ``figure`` (a path to the performance-profile figure) if given."""
    agg = verdicts.aggregate
    lines = [heading, ""] if heading else []
    if agg.empty:
        lines += [f"No aggregate: {md_text(agg.note or 'nothing to aggregate')}.", ""]
        lines += [marks_line(verdicts.families), ""]
        return "\n".join(lines)
    lines += [stats.aggregate_rule(md_text(agg.baseline or "the baseline")), ""]
    lines += [md_table(aggregate_frame(agg)), ""]
    lines += ["What the intervals support:", "", *supported_lines(agg),
              f"- {marks_line(verdicts.families)}", ""]
    left = left_out_lines(agg)
    if left:
        lines += [*left, ""]
    if figure:
        lines += [f"![Performance profiles]({figure})", ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------- tracks


def _leaders(rows: pd.DataFrame, metric: str) -> str:
    """One track's verdict on one (system, metric): ``best: <family>``, ``tied: <a>,
    <b>`` (the leader and every family not separated from it), or ``""`` (no leader:
    fewer than two ranked families with every seed ``ok``, or the track did not run)."""
    column = f"{metric}_mark"
    if column not in rows:
        return ""
    marks = rows[column].fillna("").astype(str)
    best = rows.loc[marks == "best", "family"].astype(str).tolist()
    if best:
        return f"best: {best[0]}"
    tied = rows.loc[marks == "tied", "family"].astype(str).tolist()
    return f"tied: {', '.join(tied)}" if tied else ""


def tracks_frame(fams: Families, metrics: Optional[list[str]] = None) -> pd.DataFrame:
    """The verdicts of every track side by side (docs/TUNING.md): one row per (profile,
    system, metric of ``metrics``, default the headline ones) where some track other
    than the protocol has family rows; a column per track present (its
    :func:`_leaders` text) and ``changes``: whether two tracks with a verdict name
    different leaders. Empty when every row is of the protocol track."""
    board = fams.board
    if board.empty or "track" not in board:
        return pd.DataFrame()
    if "variant" in board:
        board = board[board["variant"].fillna("").astype(str) == ""]
    board = board.assign(track=board["track"].fillna(DEFAULT_TRACK).astype(str))
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
            said = {v for v in verdicts.values() if v}
            rows.append({"profile": profile, "system": system, "metric": metric,
                         **verdicts, "changes": len(said) > 1})
    return pd.DataFrame(rows)


def tracks_markdown(frame: pd.DataFrame) -> str:
    """The tracks side by side (:func:`tracks_frame`) and one line per (system, metric)
    whose verdict changes between tracks; a line saying so when no other track ran."""
    if frame.empty:
        return ("Only the protocol track has published rows: no tuned or recipe rows yet "
                "(docs/TUNING.md).")
    shown = frame.drop(columns=["changes"]).replace("", "—")
    lines = [md_table(shown), ""]
    changed = frame[frame["changes"]]
    tracks = [c for c in frame.columns if c not in ("profile", "system", "metric", "changes")]
    if changed.empty:
        lines.append("The verdict does not change between tracks on any system and "
                     "headline metric shown.")
        return "\n".join(lines)
    lines += ["Where the verdict changes between tracks:", ""]
    for _, r in changed.iterrows():
        said = "; ".join(f"{t} {md_text(str(r[t]))}" for t in tracks if r[t])
        lines.append(f"- {md_code(str(r['system']))}, {md_code(str(r['metric']))}: {said}.")
    return "\n".join(lines)
