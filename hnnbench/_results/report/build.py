"""``write_report``: every table and figure of one or more sweeps, into one directory
(docs/ARCHITECTURE.md, "What a report holds").
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from hnnbench import _record as records
from hnnbench._contracts.text import csv_text
from hnnbench._record.loader import Unreadable
from hnnbench._results.leaderboard import leaderboard
from hnnbench._results.report.convergence import (
    convergence_figure,
    convergence_frame,
    convergence_markdown,
    read_study_summaries,
    studies_convergence,
)
from hnnbench._results.report.figures import Made, main_profile_figure, make_figures
from hnnbench._results.report.html import page
from hnnbench._results.report.inputs import ReportError, load_sweeps, provenance
from hnnbench._results.report.published import comparison_markdown
from hnnbench._results.report.selection import selection_frame, selection_markdown
from hnnbench._results.report.tables import leaderboard_markdown
from hnnbench._results.report.tuning import (
    cost_figure,
    gain_figure,
    gain_markdown,
    studies_frame,
    tuning_gain,
)
from hnnbench._results.report.verdicts import (
    Verdicts,
    aggregate_markdown,
    build_verdicts,
    tracks_frame,
    tracks_markdown,
    tuning_costs,
)

log = logging.getLogger("hnnbench")

__all__ = ["Report", "on_sweep_end", "write_report"]


@dataclass
class Report:
    out: Path
    board: pd.DataFrame
    files: dict[str, Path] = field(default_factory=dict)
    figures: list[Made] = field(default_factory=list)
    records: list[dict[str, Any]] = field(default_factory=list)
    unreadable: list[Unreadable] = field(default_factory=list)
    verdicts: Verdicts | None = None


def write_report(
    sweep_dir: Path | str | Sequence[Path | str],
    out: Path | str | None = None,
    figures: bool = True,
    strict: bool = False,
    aggregate: bool = True,
    embed_figures: bool = False,
    allow_unverified: bool = False,
    tuning: Path | str | Sequence[Path | str] | None = None,
) -> Report:
    """Build every table and figure of the sweep directories into ``out`` (default: the
    sweep, when there is one); ``figures=False`` skips the figures, ``aggregate=False``
    the aggregate across systems (a sweep's rewrite while it runs); ``strict``: every
    record is checked in full (the strict validation of every door,
    :mod:`hnnbench._results.validity`), and an unreadable or invalid record is an error
    instead of a warning (``allow_unverified``: not a record whose plugins cannot be
    verified); ``embed_figures``:
    the page holds its figures inline (base64) instead of linking them; ``tuning``:
    folders of tuned studies' summaries (``hnnbench tune``'s ``out=/tuning``, or
    results/tuning) whose convergence the tracks page shows."""
    dirs = [Path(sweep_dir)] if isinstance(sweep_dir, (str, Path)) else [Path(d) for d in sweep_dir]
    folders = (
        []
        if tuning is None
        else [Path(tuning)]
        if isinstance(tuning, (str, Path))
        else [Path(t) for t in tuning]
    )
    for folder in folders:
        if not any(folder.glob("*/*.json")):
            raise ReportError(
                f"--tuning {folder} holds no study summary (<system>/<model>.json); "
                "expected a study summary written by `hnnbench tune`: give the tuning/ "
                "folder of its out= root (or results/tuning)"
            )
    # Read (and checked) before anything is written: a summary that does not hold
    # together leaves the output as it was.
    summaries = read_study_summaries(folders)
    curves = convergence_frame(summaries)
    recs, bad = load_sweeps(dirs, strict=strict, allow_unverified=allow_unverified)
    if out is None:
        if len(dirs) != 1:
            raise ReportError("Several directories merge into one report: give --out OUT")
        out = dirs[0]
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ReportError(f"--out {out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ReportError(f"Cannot create output directory {out}: {err.strerror}") from None
    board = leaderboard(recs)
    verdicts = build_verdicts(recs, board, with_aggregate=aggregate)
    report = Report(out=out, board=board, records=recs, unreadable=bad, verdicts=verdicts)
    agg = verdicts.aggregate
    tables = {
        "csv": ("leaderboard.csv", board),
        "families": ("families.csv", verdicts.families.board),
        "twins": ("twins.csv", verdicts.families.twins),
    }
    if aggregate:
        tables.update(
            aggregate=("aggregate.csv", agg.iqm),
            improvement=("improvement.csv", agg.improvement),
            scales=("aggregate_scales.csv", agg.scales),
        )
    for key, (name, frame) in tables.items():
        report.files[key] = out / name
        records.atomic_write_text(report.files[key], csv_text(frame))
    report.figures = make_figures(recs, board, out / "figures", verdicts) if figures else []
    prov = provenance(recs)
    heatmaps = tuple(m.path.stem for m in report.figures if m.kind == "heatmap")
    report.files["md"] = out / "leaderboard.md"
    records.atomic_write_text(
        report.files["md"], leaderboard_markdown(board, verdicts.families, prov, heatmaps)
    )
    if aggregate:
        profile = main_profile_figure(report.figures)
        report.files["aggregate_md"] = out / "aggregate.md"
        records.atomic_write_text(
            report.files["aggregate_md"],
            aggregate_markdown(
                verdicts, f"figures/{profile.name}" if profile is not None else None
            ),
        )
    tracks = tracks_frame(verdicts.families)
    studies = studies_frame(recs)
    gain = tuning_gain(verdicts.families)
    convergence = studies_convergence(summaries, verdicts.families.runs)
    # A table of the tracks beside the protocol's is written only where there is one; a
    # leftover of an earlier build into the same folder (its tuned rows since withdrawn)
    # is removed, so no file in ``out`` describes records that are not there.
    for key, name, frame in (
        ("tracks", "tracks.csv", tracks),
        ("studies", "tuning_studies.csv", studies),
        ("tuning_gain", "tuning_gain.csv", gain),
        ("convergence", "tuning_convergence.csv", convergence),
    ):
        if frame.empty:
            (out / name).unlink(missing_ok=True)
            continue
        report.files[key] = out / name
        records.atomic_write_text(report.files[key], csv_text(frame))
    if figures:  # each removed where it has nothing to draw (as the tables above)
        made = cost_figure(studies, out / "figures" / "tuning_cost.png")
        if made is not None:
            report.figures.append(Made("tuned track", "tuning_cost", made))
        made = gain_figure(gain, out / "figures" / "tuning_gain.png")
        if made is not None:
            report.figures.append(Made("tuned track", "tuning_gain", made))
        made = convergence_figure(curves, out / "figures" / "tuning_convergence.png")
        if made is not None:
            report.figures.append(Made("tuned track", "tuning_convergence", made))
    report.files["tracks_md"] = out / "tracks.md"
    records.atomic_write_text(
        report.files["tracks_md"],
        "# Tracks\n\n"
        + tracks_markdown(tracks, tuning_costs(verdicts.families), gain_markdown(gain, studies))
        + (f"\n\n{text}" if (text := convergence_markdown(convergence)) else "")
        + "\n",
    )
    chosen = selection_frame(recs)
    report.files["selection"] = out / "selection.csv"
    records.atomic_write_text(report.files["selection"], csv_text(chosen))
    report.files["selection_md"] = out / "selection.md"
    records.atomic_write_text(
        report.files["selection_md"], "# Checkpoint selection\n\n" + selection_markdown(chosen)
    )
    report.files["paper"] = out / "paper_comparison.md"
    records.atomic_write_text(report.files["paper"], comparison_markdown(board))
    report.files["html"] = out / "leaderboard.html"
    records.atomic_write_text(
        report.files["html"],
        page(board, report.figures, prov, recs, bad, verdicts, base=out, embed=embed_figures),
    )
    return report


def on_sweep_end(sweep_dir: Path | str) -> None:
    """End-of-multirun hook: write the report into the sweep directory."""
    try:
        report = write_report(sweep_dir)
    except ReportError as err:
        log.warning("no report: %s", err)
        return
    for item in report.unreadable:
        log.warning("record left out: %s", item)
    print(
        f"report: {report.files['html']} (leaderboard.csv/.md, paper_comparison.md, "
        f"{len(report.figures)} figures)"
    )
