"""The checked records themselves, as ``hnnbench check`` findings: the one strict
validation of every door (:mod:`hnnbench._results.validity`), in the check's table.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from hnnbench import _record as records
from hnnbench._results import validity
from hnnbench._results.check.findings import Finding

__all__ = [
    "budget_findings",
    "findings",
    "record_variants",
    "validate_records",
]

record_variants = validity.record_variants


def findings(problems: Sequence[validity.Problem]) -> list[Finding]:
    """The validation's problems as the check's findings (the same columns)."""
    return [Finding(*dataclasses.astuple(p)) for p in problems]


def record_file(rec: dict[str, Any]) -> str:
    """Where a record was read from (its ``result.json``), or ``?``."""
    return validity.record_file(rec)


def validate_records(
    recs: Sequence[dict[str, Any]],
    bad: Sequence[records.Unreadable],
    allow_unverified: bool = False,
) -> list[Finding]:
    """The gating findings of the one strict validation, the one ``check`` runs
    (:func:`hnnbench._results.validity.validate`)."""
    return findings(validity.validate(recs, bad, allow_unverified=allow_unverified).problems)


def budget_findings(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """Unequal tuning budgets (:func:`hnnbench._results.validity.budget_problems`)."""
    return findings(validity.budget_problems(recs))
