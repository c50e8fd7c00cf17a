"""Reports from run records: the leaderboard as CSV, Markdown and HTML with its
verdicts (intervals, one competitor per family, best and tied, the aggregate across
systems: docs/STATISTICS.md), comparisons with published results and claims, and
figures.

``hnnbench report DIR [DIR ...]`` and :func:`write_report` build everything; the
pieces are importable: :mod:`~hnnbench._results.report.inputs` (records, provenance),
:mod:`~hnnbench._results.report.tables` (the family table, the twin table, every model's
row), :mod:`~hnnbench._results.report.verdicts` (the family view and the aggregate across
systems), :mod:`~hnnbench._results.report.published`,
:mod:`~hnnbench._results.report.figures` (the figure registry),
:mod:`~hnnbench._results.report.html`.
"""

from hnnbench._results.report.build import Report, on_sweep_end, write_report
from hnnbench._results.report.cli import main
from hnnbench._results.report.figures import FIGURES, figure, make_figures, runs_for_figures
from hnnbench._results.report.inputs import ReportError, load_sweep, load_sweeps, provenance
from hnnbench._results.report.published import (
    board_lookup,
    claim_results,
    claims_frame,
    comparison_frame,
    paper_claim_ratios,
    paper_table,
)

__all__ = [
    "FIGURES",
    "Report",
    "ReportError",
    "board_lookup",
    "claim_results",
    "claims_frame",
    "comparison_frame",
    "figure",
    "load_sweep",
    "load_sweeps",
    "main",
    "make_figures",
    "on_sweep_end",
    "paper_claim_ratios",
    "paper_table",
    "provenance",
    "runs_for_figures",
    "write_report",
]
