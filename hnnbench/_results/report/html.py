"""The report as one HTML page: a table of contents, the headline first, sortable
tables in a few lines of plain JavaScript, provenance collapsed, and the figures linked
from ``figures/`` beside the page and loaded lazily (``embed=True``: inline, base64, one
self-contained file); no external resource either way."""

from __future__ import annotations

import base64
import html
import math
import os
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Optional

import pandas as pd

from hnnbench import _record as records
from hnnbench._contracts.text import printable
from hnnbench._results import stats
from hnnbench._results.leaderboard import direction_header, display_frame, metric_declarations
from hnnbench._results.report.figures import FIGURES, Made
from hnnbench._results.report.inputs import provenance_lines
from hnnbench._results.report.published import claims_frame, comparison_frame
from hnnbench._results.report.tables import (
    family_display,
    reason_notes,
    reversal_note,
    seed_line,
    twins_display,
    twins_line,
)
from hnnbench._results.report.verdicts import (
    Verdicts,
    aggregate_frame,
    findings_lines,
    left_out_lines,
    marks_line,
    order_lines,
    rank_frame,
    rank_left_out_lines,
    scope_line,
    supported_lines,
)


def _esc(value: Any) -> str:
    """``value`` escaped for HTML, control characters stripped first."""
    return html.escape(printable(value))


__all__ = ["page"]

CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:24px auto;
max-width:1500px;padding:0 16px;color:#222}
h1{font-size:1.6em;margin-bottom:.3em}
h2{margin-top:1.6em;border-bottom:1px solid #ddd;padding-bottom:4px}
table{border-collapse:collapse;font-size:13px;margin:8px 0}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right;white-space:nowrap}
th{background:#f3f3f3}td.txt,th.txt{text-align:left}
table.sortable th{cursor:pointer}table.sortable th:hover{background:#e4e4e4}
th[data-dir=asc]::after{content:" ▲"}th[data-dir=desc]::after{content:" ▼"}
tr:nth-child(even) td{background:#fafafa}
td.best,tr:nth-child(even) td.best{background:#cfe2f3;font-weight:bold}
td.tied,tr:nth-child(even) td.tied{background:#e8f1fa;font-style:italic}
td.unbeaten,tr:nth-child(even) td.unbeaten{background:#f3e6cc}
.wrap{overflow-x:auto}
td.diverged,td.inf{color:#b35900}td.reproduced{color:#0072b2}td.notrep{color:#b35900}
td.notrun{color:#888}
.claims td.txt{white-space:normal}
img{max-width:100%;height:auto;border:1px solid #eee;margin:6px 0}
.note{color:#555;font-size:13px}
nav.toc{font-size:14px;background:#f7f7f7;border:1px solid #e3e3e3;padding:6px 12px}
nav.toc ul{display:flex;flex-wrap:wrap;gap:2px 16px;list-style:none;margin:2px 0;padding:0}
nav.toc li.systems{flex-basis:100%}nav.toc ul.systems{display:inline-flex;gap:2px 12px}
details{margin:8px 0}details>summary{cursor:pointer;color:#444}
ol.notes{font-size:13px;color:#444}ol.notes li{margin:2px 0}
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

_TEXT_COLUMNS = {
    "system",
    "model",
    "variant",
    "status",
    "task",
    "metric",
    "source",
    "claim",
    "backend",
    "result",
    "our numbers",
    "path",
    "reason",
    "family",
    "seeds_from",
    "twins",
    "twin",
    "seeds from",
    "shared seeds",
    "agree",
    "difference",
}


def _sort_value(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float) and math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return repr(float(value))


def _table(
    frame: pd.DataFrame,
    cls: str = "",
    status_col: Optional[str] = None,
    numbers: Optional[pd.DataFrame] = None,
    marks: Optional[dict[tuple[int, str], str]] = None,
) -> str:
    """An HTML table of ``frame`` (display strings); ``numbers`` holds the numeric sort
    keys of its metric columns (same rows), ``marks`` the cells to highlight
    (``"best"`` or ``"tied"``)."""
    txt = ' class="txt"'
    declared = metric_declarations()
    head = "".join(
        f"<th{txt if c in _TEXT_COLUMNS else ''}>{_esc(direction_header(c, declared))}</th>"
        for c in frame.columns
    )
    body = []
    for i, (_, row) in enumerate(frame.iterrows()):
        cells = []
        for col in frame.columns:
            value = str(row[col])
            classes = ["txt"] if col in _TEXT_COLUMNS else []
            if col == status_col:
                outcome = {
                    "reproduced": "reproduced",
                    "not reproduced": "notrep",
                    "not run": "notrun",
                }.get(value)
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
                attrs += f' data-v="{_esc(value)}"'
            cells.append(f"<td{attrs}>{_esc(value)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (
        f'<div class="wrap"><table class="{cls}"><thead><tr>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table></div>"
    )


def _inline_code(markdown: str) -> str:
    """Escape ``markdown`` for HTML, turning its `code` spans into <code> elements."""
    parts = markdown.split("`")
    return "".join(f"<code>{_esc(p)}</code>" if i % 2 else _esc(p) for i, p in enumerate(parts))


def _png_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG's header, or ``None`` when it is not one."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", head[16:24])
    return int(width), int(height)


def _img(path: Path, alt: str, base: Path | None = None, embed: bool = False) -> str:
    """An ``<img>`` of the figure at ``path``: linked relative to the page's directory
    ``base`` and loaded lazily, or inline (base64) with ``embed``; its pixel size is
    given so the page does not jump while figures load."""
    size = _png_size(path)
    dims = f' width="{size[0]}" height="{size[1]}"' if size else ""
    if embed:
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        return f'<img alt="{_esc(alt)}"{dims} src="data:image/png;base64,{data}">'
    where = Path(os.path.relpath(path, base)) if base is not None else Path(path)
    return f'<img loading="lazy" alt="{_esc(alt)}"{dims} src="{_esc(where.as_posix())}">'


def _provenance_table(recs: Sequence[dict[str, Any]]) -> pd.DataFrame:
    rows: dict[tuple[str, str, str], dict[str, Any]] = {}
    for rec in recs:
        env = rec.get("environment") or {}
        key = (
            str(rec.get("source") or ""),
            str(env.get("git_commit") or "?"),
            str(env.get("host") or env.get("platform") or "?"),
        )
        row = rows.setdefault(
            key,
            {
                "source": key[0],
                "commit": key[1][:12],
                "machine": key[2],
                "records": 0,
                "dates": set(),
            },
        )
        row["records"] += 1
        row["dates"].add(str(rec.get("created_at") or "")[:10])
    out = []
    for row in rows.values():
        dates = sorted(d for d in row.pop("dates") if d)
        row["dates"] = (
            f"{dates[0]} – {dates[-1]}" if len(dates) > 1 else (dates[0] if dates else "?")
        )
        out.append(row)
    return pd.DataFrame(out)


def _aggregate_section(verdicts: Verdicts, figures: list[Made], img: Any) -> list[str]:
    """The headline as aggregate.md has it: the mean ranks (free of any normalisation)
    first, what the intervals of P(A > B) support, the separated bests with their
    effects, then the IQM of normalised scores as a second view and how its order hangs
    on the floor, then the performance profiles (``img(made)``: the figure's tag)."""
    agg, key = verdicts.aggregate, verdicts.main
    parts = ['<h2 id="across">Across systems</h2>']
    scope = scope_line(verdicts)
    if scope:
        parts.append(f'<p class="note">{_inline_code(scope)}</p>')
    ranks = rank_frame(agg, key=key) if not agg.ranks.empty else pd.DataFrame()
    table = aggregate_frame(agg, key=key) if not agg.iqm.empty else pd.DataFrame()
    if ranks.empty and table.empty:
        why = agg.note if agg.empty else "no (system, metric) of this scope is normalised"
        parts.append(f'<p class="note">No aggregate: {_esc(why or "nothing to aggregate")}.</p>')
        parts += [f'<p class="note">{_inline_code(line)}</p>' for line in left_out_lines(agg, key)]
        return parts
    if not ranks.empty:
        parts.append(f'<p class="note">{_inline_code(stats.rank_rule())}</p>')
        parts.append(_table(ranks, "aggregate"))
        parts += [
            f'<p class="note">{_inline_code(line)}</p>' for line in rank_left_out_lines(agg, key)
        ]
    parts.append('<p class="note">What the intervals support:</p><ul>')
    parts += [f"<li>{_inline_code(line[2:])}</li>" for line in supported_lines(agg, key=key)]
    parts.append(f"<li>{_inline_code(marks_line(verdicts.families, key=key))}</li></ul>")
    found = findings_lines(verdicts.families, key)
    if found:
        parts.append(
            '<p class="note">Separated bests per system, with the leader\'s median paired '
            "effect over the runner-up [interval] (×: a factor on a log-scale metric, +: a "
            "difference):</p><ul>"
        )
        parts += [f"<li>{_inline_code(line[2:])}</li>" for line in found]
        parts.append("</ul>")
    if not table.empty:
        rule = stats.aggregate_rule(agg.baseline or "the baseline")
        parts.append(
            f'<p class="note">A second view, which depends on a choice of scale: '
            f"{_inline_code(rule)}</p>"
        )
        parts.append(_table(table, "aggregate-iqm"))
        moves = order_lines(agg, key)
        if moves:
            parts.append(
                f'<p class="note">How its order hangs on the floor: '
                f"{_inline_code(' '.join(moves))}</p>"
            )
    parts += [f'<p class="note">{_inline_code(line)}</p>' for line in left_out_lines(agg, key)]
    parts += [img(m) for m in figures if m.kind == "profile"]
    return parts


def _anchor(label: str) -> str:
    """An element id for a figure section's label (letters, digits, ``-``, ``_``)."""
    return "fig-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in label)


def _toc(entries: Sequence[tuple[str, str]], systems: Sequence[str]) -> str:
    """The table of contents: ``(id, title)`` of each section, and the figure sections'
    labels in a row of their own."""
    items = [f'<li><a href="#{_esc(i)}">{_esc(t)}</a></li>' for i, t in entries]
    if systems:
        links = "".join(
            f'<li><a href="#{_esc(_anchor(label))}">{_esc(label)}</a></li>' for label in systems
        )
        items.append(
            f'<li class="systems">Figures by system: <ul class="systems">{links}</ul></li>'
        )
    return f'<nav class="toc"><b>Contents</b><ul>{"".join(items)}</ul></nav>'


def page(
    board: pd.DataFrame,
    figures: list[Made],
    prov: dict[str, list[str]],
    recs: Sequence[dict[str, Any]],
    unreadable: Sequence[records.Unreadable] = (),
    verdicts: Optional[Verdicts] = None,
    *,
    base: Optional[Path] = None,
    embed: bool = False,
) -> str:
    """The whole page: the figures linked relative to ``base`` (the page's directory)
    and loaded lazily, or inline with ``embed`` (one self-contained file)."""
    if verdicts is None:
        from hnnbench._results.report.verdicts import build_verdicts

        verdicts = build_verdicts(list(recs), board)

    def img(made: Made, alt: str = "") -> str:
        return _img(made.path, alt or made.path.stem, base, embed)

    fams = verdicts.families
    shown_board = fams.board if not fams.board.empty else board
    heatmaps = [m for m in figures if m.kind == "heatmap"]
    comparison = comparison_frame(board)
    titles = {kind.name: kind.title for kind in FIGURES.values()}
    sections: dict[str, list[Made]] = {}
    for made in figures:
        if made.kind not in ("heatmap", "profile"):
            sections.setdefault(made.label, []).append(made)
    entries = [
        ("across", "Across systems"),
        ("families", "Families"),
        *([("heatmaps", "Which family wins where")] if heatmaps else []),
        ("twins", "Twin agreement"),
        ("models", "Every model"),
        *([("published", "Comparison with published results")] if not comparison.empty else []),
        ("claims", "Qualitative claims from the literature"),
        ("provenance", "Provenance"),
    ]
    provenance = [f"<li>{_inline_code(line[2:])}</li>" for line in provenance_lines(prov)]
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        "<title>hnnbench leaderboard</title>",
        f"<style>{CSS}</style></head><body>",
        "<h1>hnnbench leaderboard</h1>",
        _toc(entries, list(sections)),
        "<details><summary>What the rows are, and where the records come from "
        "(commands, commits, machines)</summary>"
        f'<p class="note">{_inline_code(seed_line(shown_board))}</p>'
        f'<ul class="note">{"".join(provenance)}</ul></details>',
    ]
    parts += _aggregate_section(verdicts, figures, img)
    shown, marks = family_display(fams)
    shown, notes = reason_notes(shown)
    parts += [
        '<h2 id="families">Families</h2>',
        '<p class="note">One row per family: its primary twin\'s seeds (<code>seeds_from</code>); '
        "click a column header to sort; \u2193 lower is better, \u2191 higher is better. "
        f"{_inline_code(stats.best_rule().replace('**', '').replace('*', ''))} "
        "Highlighted: best (bold) and tied (italics); a standing-still cell that no "
        "family's leader improves on is shaded.</p>",
        _table(
            shown,
            "board sortable",
            status_col="status",
            numbers=fams.board.reset_index(drop=True),
            marks=marks,
        ),
    ]
    if notes:
        parts.append(
            '<p class="note">Why runs did not finish <code>ok</code> ([n] after a '
            'status):</p><ol class="notes">'
            + "".join(f'<li value="{n}">{_esc(reason)}</li>' for n, reason in notes)
            + "</ol>"
        )
    note = reversal_note(board)
    if note:
        parts.append(f'<p class="note">{_inline_code(note)}</p>')
    if heatmaps:
        parts.append('<h2 id="heatmaps">Which family wins where</h2>')
        parts.append(
            '<p class="note">Rank of each ranked family within each system '
            "(1 = best, mean below it; best and tied as in the table); rows "
            "without a variant only.</p>"
        )
        parts += [img(m) for m in heatmaps]
    parts += [
        '<h2 id="twins">Twin agreement</h2>',
        f'<p class="note">{_inline_code(twins_line(fams))}</p>',
    ]
    twins = twins_display(fams)
    if not twins.empty:
        parts.append(_table(twins, "twins sortable"))
    parts += [
        '<h2 id="models">Every model</h2>',
        '<p class="note">Both twins of every family, unmarked: the verdicts are the '
        "families'.</p>",
        _table(
            display_frame(board),
            "models sortable",
            status_col="status",
            numbers=board.reset_index(drop=True),
        ),
    ]
    if not comparison.empty:
        parts += [
            '<h2 id="published">Comparison with published results</h2>',
            '<p class="note">Natural units; details in paper_comparison.md.</p>',
            _table(comparison, "paper"),
        ]
    parts += [
        '<h2 id="claims">Qualitative claims from the literature</h2>',
        _table(claims_frame(board), "claims sortable", status_col="result"),
    ]
    for label, made_list in sections.items():
        parts.append(f'<h2 id="{_esc(_anchor(label))}">{_esc(label)}</h2>')
        for made in made_list:
            parts.append(f"<h3>{_esc(titles.get(made.kind, made.kind))}</h3>")
            parts.append(img(made, f"{label} {made.kind}"))
    parts += [
        '<h2 id="provenance">Provenance</h2>',
        "<details><summary>Where the records come from: one row per (directory, "
        "commit, machine)</summary>",
        _table(_provenance_table(recs), "prov sortable"),
        "</details>",
    ]
    if unreadable:
        parts += [
            "<h2>Unreadable records (left out)</h2>",
            _table(
                pd.DataFrame([{"path": str(u.path), "reason": u.reason} for u in unreadable]), "bad"
            ),
        ]
    parts.append(
        '<p class="note">Generated by <code>hnnbench report</code> from the run '
        f"records.</p><script>{SORT_JS}</script></body></html>"
    )
    return "\n".join(parts) + "\n"
