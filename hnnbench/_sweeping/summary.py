"""Hydra callbacks: the end-of-sweep summary."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from hnnbench._contracts.text import csv_text

log = logging.getLogger("hnnbench")

__all__ = ["SweepSummary", "print_summary"]


def _this_run() -> list[dict[str, Any]] | None:
    """The outcomes this command's jobs have reported so far (``{"record", "kept"}``, or
    ``{"lost"}``), or ``None`` outside the hnnbench command and API."""
    from hnnbench._running import launch_context

    context = launch_context.local()
    return None if context is None else list(context.outcomes)


def _counts_line(total: int, outcomes: list[dict[str, Any]] | None, counts: dict[str, int]) -> str:
    """``N jobs: ...`` of the directory, or of this run when its outcomes are known:
    this run's jobs by status, those kept from an earlier run, and how many records the
    directory holds when it holds others (another sweep's, or other settings')."""
    directory = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
    if outcomes is None:
        return f"{total} jobs: {directory}"
    new: dict[str, int] = {}
    kept = lost = 0
    for outcome in outcomes:
        if "lost" in outcome:
            lost += 1
        elif outcome.get("kept"):
            kept += 1
        else:
            status = str(outcome.get("record", {}).get("status"))
            new[status] = new.get(status, 0) + 1
    if lost:
        new["returned no record"] = lost
    ran = sum(new.values())
    line = f"this run: {ran} jobs: " + (
        ", ".join(f"{n} {s}" for s, n in sorted(new.items())) or "none run"
    )
    if kept:
        line += f"; {kept} kept from an earlier run"
    if total != ran - lost + kept:  # other sweeps' records, or other settings'
        line += f"; {total} records in the directory in all"
    return line


def print_summary(sweep_dir: Path) -> None:
    """Print the Markdown summary of the records under ``sweep_dir``; write summary.csv.
    Its last line counts this run's jobs by status (records kept from an earlier run
    apart, and the directory's total when it holds other records) when run by the
    hnnbench command or API, else the directory's records."""
    from hnnbench import _record as records
    from hnnbench._results.leaderboard import (
        direction_header,
        records_frame,
        summary_frame,
        summary_metrics,
    )

    recs, bad = records.load(sweep_dir)
    for item in bad:
        log.warning("record left out: %s", item)
    frames = records_frame(recs)
    frame = summary_frame(frames)  # every metric, for summary.csv
    if frame.empty:
        log.warning("no run records under %s", sweep_dir)
        return
    (sweep_dir / "summary.csv").write_text(csv_text(frame), encoding="utf-8")
    counts = frame["status"].value_counts().to_dict()
    shown = summary_frame(frames, summary_metrics())
    shown = shown[[c for c in shown.columns if not shown[c].isna().all()]]  # none applies
    shown = shown.rename(columns=direction_header)  # energy_mse ↓, rollout_skill ↑
    print()
    print(shown.to_markdown(index=False, floatfmt=".3g"))
    print()
    print(_counts_line(len(frame), _this_run(), counts))
    print(f"records and summary.csv in {sweep_dir}")


class SweepSummary(Callback):
    """At the end of a multirun, summarise every record in the sweep directory."""

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        try:
            print_summary(sweep_dir)
        except Exception as err:  # a summary problem must not hide the finished runs
            log.error("could not summarise %s: %s", sweep_dir, err)
        try:
            from hnnbench._results import report
        except ImportError:
            return
        hook = getattr(report, "on_sweep_end", None)
        if hook is not None:
            try:
                hook(sweep_dir)
            except Exception as err:
                log.error("could not build the report for %s: %s", sweep_dir, err)
