"""Flatten run records into pandas tables."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import pandas as pd

__all__ = ["SUMMARY_METRICS", "records_frame", "summary_frame"]

#: Metrics shown in the end-of-sweep summary, in order.
SUMMARY_METRICS = (
    "train_loss",
    "test_loss",
    "energy_mse",
    "reversibility_error",
    "rollout_mse",
    "time_reversal_error",
    "valid_prediction_time",
)


def records_frame(records: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """One row per record: identity columns, ``<metric>`` means, ``<metric>_sem`` and
    ``<timing>`` columns."""
    rows = []
    for rec in records:
        row: dict[str, Any] = {
            "system": rec.get("system"),
            "model": rec.get("model"),
            "backend": rec.get("backend"),
            "seed": rec.get("seed"),
            "profile": rec.get("profile"),
            "status": rec.get("status"),
            "error": rec.get("error"),
            "steps": rec.get("steps"),
            "device": rec.get("device"),
            "path": rec.get("path"),
        }
        for name, value in (rec.get("metrics") or {}).items():
            row[name] = value.get("mean")
            row[f"{name}_sem"] = value.get("sem")
        for name, value in (rec.get("timings") or {}).items():
            row[name] = value
        rows.append(row)
    return pd.DataFrame(rows)


def summary_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per (system, model, seed) with the summary metrics and status."""
    if frame.empty:
        return frame
    cols = ["system", "model", "seed", "status"]
    cols += [m for m in SUMMARY_METRICS if m in frame.columns]
    cols += [c for c in ("total_s",) if c in frame.columns]
    return frame[cols].sort_values(["system", "model", "seed"]).reset_index(drop=True)
