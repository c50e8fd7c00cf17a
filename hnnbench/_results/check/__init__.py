"""``hnnbench check DIR [DIR ...] --reference CSV``: the leaderboard regression gate and
the validation of submitted records (docs/LEADERBOARD.md, "hnnbench check").

The modules, one concept each: :mod:`~hnnbench._results.check.rules` (each metric's
tolerance), :mod:`~hnnbench._results.check.reference` (the reference CSV),
:mod:`~hnnbench._results.check.compare` (row by row), :mod:`~hnnbench._results.check.
ranks` (a new model's rank interval), :mod:`~hnnbench._results.check.records` (the
records themselves), :mod:`~hnnbench._results.check.rerun` (``--rerun``),
:mod:`~hnnbench._results.check.findings` (what is found, and what to do about it) and
:mod:`~hnnbench._results.check.command` (the command). Their API is re-exported here.
"""

from hnnbench._results.check.command import main
from hnnbench._results.check.compare import compare
from hnnbench._results.check.findings import (
    HEADERS,
    CheckError,
    CheckResult,
    Finding,
    missing_line,
    update_hint,
)
from hnnbench._results.check.ranks import Rank, rank_lines
from hnnbench._results.check.records import (
    budget_findings,
    record_variants,
    validate_records,
)
from hnnbench._results.check.reference import (
    COUNT_COLUMNS,
    KEY,
    REQUIRED_COLUMNS,
    read_reference,
    row_key,
)
from hnnbench._results.check.rerun import DATA_HASHES, Rerun, rerun, rerun_config
from hnnbench._results.check.rules import TIMING_RULE, declared_rules, load_rules

__all__ = [
    "COUNT_COLUMNS",
    "DATA_HASHES",
    "HEADERS",
    "KEY",
    "REQUIRED_COLUMNS",
    "TIMING_RULE",
    "CheckError",
    "CheckResult",
    "Finding",
    "Rank",
    "Rerun",
    "budget_findings",
    "compare",
    "declared_rules",
    "load_rules",
    "main",
    "missing_line",
    "rank_lines",
    "read_reference",
    "record_variants",
    "rerun",
    "rerun_config",
    "row_key",
    "update_hint",
    "validate_records",
]
