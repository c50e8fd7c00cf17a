"""Hydra callbacks: the end-of-sweep summary."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

log = logging.getLogger("hnnbench")

__all__ = ["SweepSummary", "print_summary"]


def print_summary(sweep_dir: Path) -> None:
    """Print the Markdown summary of the records under ``sweep_dir``; write summary.csv."""
    from hnnbench import _records as records
    from hnnbench._table import records_frame, summary_frame, summary_metrics

    recs, bad = records.load(sweep_dir)
    for item in bad:
        log.warning("record left out: %s", item)
    frames = records_frame(recs)
    frame = summary_frame(frames)  # every metric, for summary.csv
    if frame.empty:
        log.warning("no run records under %s", sweep_dir)
        return
    frame.to_csv(sweep_dir / "summary.csv", index=False)
    counts = frame["status"].value_counts().to_dict()
    shown = summary_frame(frames, summary_metrics())
    shown = shown[[c for c in shown.columns if not shown[c].isna().all()]]
    print()
    print(shown.to_markdown(index=False, floatfmt=".3g"))
    print()
    print(f"{len(frame)} jobs: " + ", ".join(f"{n} {s}" for s, n in sorted(counts.items())))
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
            from hnnbench import _report as report
        except ImportError:
            return
        hook = getattr(report, "on_sweep_end", None)
        if hook is not None:
            try:
                hook(sweep_dir)
            except Exception as err:
                log.error("could not build the report for %s: %s", sweep_dir, err)
