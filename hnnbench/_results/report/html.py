"""The report as one self-contained HTML page: figures inline (base64), sortable
tables in a few lines of plain JavaScript, no external resource."""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Optional

import pandas as pd

from hnnbench import _record as records
from hnnbench._results import stats
from hnnbench._results.leaderboard import display_frame
from hnnbench._results.report.figures import FIGURES, Made
from hnnbench._results.report.inputs import provenance_lines
from hnnbench._results.report.published import claims_frame, comparison_frame
from hnnbench._results.report.tables import (
    family_display,
    reversal_note,
    seed_line,
    twins_display,
    twins_line,
)
from hnnbench._results.report.verdicts import (
    Verdicts,
    aggregate_frame,
    left_out_lines,
    marks_line,
    scope_line,
    supported_lines,
)

__all__ = ["page"]

CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:24px auto;
max-width:1500px;padding:0 16px;color:#222}
h1{font-size:1.6em}h2{margin-top:1.6em;border-bottom:1px solid #ddd;padding-bottom:4px}
table{border-collapse:collapse;font-size:13px;margin:8px 0}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right;white-space:nowrap}
th{background:#f3f3f3}td.txt,th.txt{text-align:left}
table.sortable th{cursor:pointer}table.sortable th:hover{background:#e4e4e4}
th[data-dir=asc]::after{content:" ▲"}th[data-dir=desc]::after{content:" ▼"}
tr:nth-child(even) td{background:#fafafa}
td.best,tr:nth-child(even) td.best{background:#d9f2d9;font-weight:bold}
td.tied,tr:nth-child(even) td.tied{background:#eef8ee;font-style:italic}
td.unbeaten,tr:nth-child(even) td.unbeaten{background:#f3e6cc}
.wrap{overflow-x:auto}
td.diverged,td.inf{color:#b00}td.reproduced{color:#070}td.notrep{color:#b00}
td.notrun{color:#888}
.claims td.txt{white-space:normal}
img{max-width:100%;border:1px solid #eee;margin:6px 0}
.note{color:#555;font-size:13px}
"""

#: Click a header to sort by it (again: reverse). Numeric cells sort by ``data-v``.
SORT_JS = """
document.querySelectorAll("table.sortable th").forEach(function (th, col) {
  th.addEventListener("click", function () {
    var body = th.closest("table").tBodies[0];
    var asc = th.dataset.dir !== "asc";
    th.closest("tr").querySelectorAll("th").forEach(function (h) { delete h.dataset.dir; });
    th.dataset.dir = asc ? "asc" : "desc";
    function key(row) {
      var cell = row.cells[col], v = cell.dataset.v;
      return v === undefined ? cell.textContent : (v === "" ? NaN : parseFloat(v));
    }
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = key(a), y = key(b), c;
      if (typeof x === "number" && typeof y === "number") {
        if (isNaN(x) || isNaN(y)) { return isNaN(x) - isNaN(y); }
        c = x - y;
      } else { c = String(x).localeCompare(String(y)); }
      return asc ? c : -c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});
"""

_TEXT_COLUMNS = {"system", "model", "variant", "status", "task", "metric", "source", "claim",
                 "backend", "result", "our numbers", "path", "reason", "family",
                 "seeds_from", "twins", "twin", "seeds from", "shared seeds", "agree",
                 "difference"}


def _sort_value(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float) and math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return repr(float(value))


def _table(frame: pd.DataFrame, cls: str = "", status_col: Optional[str] = None,
           numbers: Optional[pd.DataFrame] = None,
           marks: Optional[dict[tuple[int, str], str]] = None) -> str:
    """An HTML table of ``frame`` (display strings); ``numbers`` holds the numeric sort
    keys of its metric columns (same rows), ``marks`` the cells to highlight
    (``"best"`` or ``"tied"``)."""
    txt = ' class="txt"'
    head = "".join(f"<th{txt if c in _TEXT_COLUMNS else ''}>{html.escape(str(c))}</th>"
                   for c in frame.columns)
    body = []
    for i, (_, row) in enumerate(frame.iterrows()):
        cells = []
        for col in frame.columns:
            value = str(row[col])
            classes = ["txt"] if col in _TEXT_COLUMNS else []
            if col == status_col:
                outcome = {"reproduced": "reproduced", "not reproduced": "notrep",
                           "not run": "notrun"}.get(value)
                if outcome:
                    classes.append(outcome)
                elif "diverged" in value or "failed" in value:
                    classes.append("diverged")
            elif value == "inf":
                classes.append("inf")
            if marks and (i, col) in marks:
                classes.append(marks[(i, col)])
                effect = marks.get((i, f"{col}:effect"))
                if effect:  # the leader's median paired effect over the runner-up
                    value = f"{value} {effect}"
            attrs = f' class="{" ".join(classes)}"' if classes else ""
            if numbers is not None and f"{col}_mean" in numbers.columns:
                attrs += f' data-v="{_sort_value(numbers.iloc[i][f"{col}_mean"])}"'
            elif col in ("n_seeds",):
                attrs += f' data-v="{html.escape(value)}"'
            cells.append(f"<td{attrs}>{html.escape(value)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (f'<div class="wrap"><table class="{cls}"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table></div>")


def _inline_code(markdown: str) -> str:
    """Escape ``markdown`` for HTML, turning its `code` spans into <code> elements."""
    parts = markdown.split("`")
    return "".join(f"<code>{html.escape(p)}</code>" if i % 2 else html.escape(p)
                   for i, p in enumerate(parts))


def _img(path: Path, alt: str) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _provenance_table(recs: Sequence[dict[str, Any]]) -> pd.DataFrame:
    rows: dict[tuple[str, str, str], dict[str, Any]] = {}
    for rec in recs:
        env = rec.get("environment") or {}
        key = (str(rec.get("source") or ""), str(env.get("git_commit") or "?"),
               str(env.get("host") or env.get("platform") or "?"))
        row = rows.setdefault(key, {"source": key[0], "commit": key[1][:12], "machine": key[2],
                                    "records": 0, "dates": set()})
        row["records"] += 1
        row["dates"].add(str(rec.get("created_at") or "")[:10])
    out = []
    for row in rows.values():
        dates = sorted(d for d in row.pop("dates") if d)
        row["dates"] = f"{dates[0]} – {dates[-1]}" if len(dates) > 1 else (dates[0] if dates
                                                                          else "?")
        out.append(row)
    return pd.DataFrame(out)


def _aggregate_section(verdicts: Verdicts, figures: list[Made]) -> list[str]:
    agg, key = verdicts.aggregate, verdicts.main
    parts = ["<h2>Across systems</h2>"]
    scope = scope_line(verdicts)
    if scope:
        parts.append(f'<p class="note">{_inline_code(scope)}</p>')
    table = aggregate_frame(agg, key=key) if not agg.empty else pd.DataFrame()
    if table.empty:
        why = agg.note if agg.empty else "no (system, metric) of this scope is normalised"
        parts.append(f'<p class="note">No aggregate: {html.escape(why)}.</p>')
        parts += [f'<p class="note">{_inline_code(line)}</p>'
                  for line in left_out_lines(agg, key)]
        return parts
    rule = stats.aggregate_rule(agg.baseline or "the baseline")
    parts += [f'<p class="note">{_inline_code(rule)}</p>',
              _table(table, "aggregate"),
              '<p class="note">What the intervals support:</p><ul>']
    parts += [f"<li>{_inline_code(line[2:])}</li>" for line in supported_lines(agg, key=key)]
    parts.append(f"<li>{_inline_code(marks_line(verdicts.families, key=key))}</li></ul>")
    parts += [f'<p class="note">{_inline_code(line)}</p>' for line in left_out_lines(agg, key)]
    parts += [_img(m.path, m.path.stem) for m in figures if m.kind == "profile"]
    return parts


def page(board: pd.DataFrame, figures: list[Made], prov: dict[str, list[str]],
         recs: Sequence[dict[str, Any]], unreadable: Sequence[records.Unreadable] = (),
         verdicts: Optional[Verdicts] = None) -> str:
    """The whole page."""
    if verdicts is None:
        from hnnbench._results.report.verdicts import build_verdicts

        verdicts = build_verdicts(list(recs), board)
    fams = verdicts.families
    shown_board = fams.board if not fams.board.empty else board
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        "<title>hnnbench leaderboard</title>", f"<style>{CSS}</style></head><body>",
        "<h1>hnnbench leaderboard</h1>",
        f'<p class="note">{_inline_code(seed_line(shown_board))}</p>',
        *[f'<p class="note">{_inline_code(line[2:])}</p>' for line in provenance_lines(prov)],
    ]
    parts += _aggregate_section(verdicts, figures)
    shown, marks = family_display(fams)
    parts += [
        "<h2>Families</h2>",
        '<p class="note">One row per family: its primary twin\'s seeds (<code>seeds_from</code>); '
        "click a column header to sort. "
        f"{_inline_code(stats.best_rule().replace('**', '').replace('*', ''))} "
        "Highlighted: best (bold) and tied (italics); a standing-still cell that no "
        "family's leader improves on is shaded.</p>",
        _table(shown, "board sortable", status_col="status",
               numbers=fams.board.reset_index(drop=True), marks=marks),
    ]
    note = reversal_note(board)
    if note:
        parts.append(f'<p class="note">{_inline_code(note)}</p>')
    heatmaps = [m for m in figures if m.kind == "heatmap"]
    if heatmaps:
        parts.append("<h2>Which family wins where</h2>")
        parts.append('<p class="note">Rank of each ranked family within each system '
                     "(1 = best, mean below it; best and tied as in the table); rows "
                     "without a variant only.</p>")
        parts += [_img(m.path, m.path.stem) for m in heatmaps]
    parts += ["<h2>Twin agreement</h2>", f'<p class="note">{_inline_code(twins_line(fams))}</p>']
    twins = twins_display(fams)
    if not twins.empty:
        parts.append(_table(twins, "twins sortable"))
    parts += [
        "<h2>Every model</h2>",
        '<p class="note">Both twins of every family, unmarked: the verdicts are the '
        "families'.</p>",
        _table(display_frame(board), "models sortable", status_col="status",
               numbers=board.reset_index(drop=True)),
    ]
    comparison = comparison_frame(board)
    if not comparison.empty:
        parts += ["<h2>Comparison with published results</h2>",
                  '<p class="note">Natural units; details in paper_comparison.md.</p>',
                  _table(comparison, "paper")]
    parts += ["<h2>Qualitative claims from the literature</h2>",
              _table(claims_frame(board), "claims sortable", status_col="result")]
    titles = {kind.name: kind.title for kind in FIGURES.values()}
    sections: dict[str, list[Made]] = {}
    for made in figures:
        if made.kind not in ("heatmap", "profile"):
            sections.setdefault(made.label, []).append(made)
    for label, made_list in sections.items():
        parts.append(f'<h2 id="{html.escape(label)}">{html.escape(label)}</h2>')
        for made in made_list:
            parts.append(f"<h3>{html.escape(titles.get(made.kind, made.kind))}</h3>")
            parts.append(_img(made.path, f"{label} {made.kind}"))
    parts += ["<h2>Provenance</h2>",
              '<p class="note">Where the records come from: one row per (directory, commit, '
              "machine).</p>", _table(_provenance_table(recs), "prov sortable")]
    if unreadable:
        parts += ["<h2>Unreadable records (left out)</h2>",
                  _table(pd.DataFrame([{"path": str(u.path), "reason": u.reason}
                                       for u in unreadable]), "bad")]
    parts.append('<p class="note">Generated by <code>hnnbench report</code> from the run '
                 f"records.</p><script>{SORT_JS}</script></body></html>")
    return "\n".join(parts) + "\n"
