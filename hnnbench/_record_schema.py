"""The run record's names, declared once: its identity fields, statuses, timings and
the leaderboard columns built from them, and the rule a metric name must follow so that
it never takes one of those names.

A contract (it imports nothing else of hnnbench): the registry checks metric names
against it, the leaderboard and the gate take their column names from it.
"""

from __future__ import annotations

import re
from typing import Optional

__all__ = [
    "ID_COLUMNS",
    "PROVENANCE_COLUMNS",
    "RESERVED",
    "STATUS_COLUMNS",
    "TIMINGS",
    "metric_name_problem",
]

#: Timings averaged into the leaderboard (``<name>_mean``).
TIMINGS = ("fit_s", "eval_s", "total_s")
#: Identity and status columns of a leaderboard, in order.
ID_COLUMNS = ("profile", "system", "model", "backend", "family", "ranked")
STATUS_COLUMNS = ("n_seeds", "seeds", "n_ok", "n_diverged", "n_failed", "n_skipped",
                  "n_timeout", "status")
#: Provenance columns of a leaderboard: distinct values over the pair's records.
PROVENANCE_COLUMNS = ("git_commits", "machines", "dates")
#: Columns of a records frame that are not metrics.
RESERVED = frozenset({"system", "model", "variant", "backend", "family", "ranked", "seed",
                      "profile",
                      "status", "error", "steps", "device", "path", "source", "git_commit",
                      "machine", "created_at"})


def metric_name_problem(name: str) -> Optional[str]:
    """Why ``name`` cannot name a metric, or ``None``. Metrics share a records frame
    with identity fields and timings, and a leaderboard with status columns and the
    ``_mean``/``_std`` columns built from them, so a metric may not take those names."""
    taken = RESERVED | set(STATUS_COLUMNS) | set(PROVENANCE_COLUMNS) | set(TIMINGS)
    if not re.fullmatch(r"[a-z][a-z0-9_]*", name):
        return f"'{name}' is not a metric name: use lower-case letters, digits and '_'"
    if name in taken:
        return f"the metric name '{name}' is a leaderboard column; choose another name"
    for suffix in ("_s", "_sem", "_mean", "_std"):
        if name.endswith(suffix):
            return (f"the metric name '{name}' ends in '{suffix}', which tables reserve "
                    "for timings and aggregates; choose another name")
    return None
