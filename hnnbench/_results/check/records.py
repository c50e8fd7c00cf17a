"""The checked records themselves, as ``hnnbench check`` findings: the one strict
validation of every door (:mod:`hnnbench._results.validity`), in the check's table.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hnnbench import _record as records
from hnnbench._results import provenance, validity
from hnnbench._results.check.findings import Finding

__all__ = [
    "budget_findings",
    "findings",
    "plugin_information",
    "record_variants",
    "validate_records",
    "variant_findings",
]

record_variants = validity.record_variants


def findings(problems: Sequence[validity.Problem]) -> list[Finding]:
    """The validation's problems as the check's findings (the same columns)."""
    return [Finding(*dataclasses.astuple(p)) for p in problems]


def record_file(rec: dict[str, Any]) -> str:
    return str(Path(rec["path"]) / records.RECORD_NAME) if rec.get("path") else "?"


def variant_findings(
    recs: Sequence[dict[str, Any]], variants: Sequence[provenance.Variant]
) -> tuple[list[Finding], list[Finding]]:
    """``(regressions, information)`` about the records' variants
    (:func:`hnnbench._results.validity.variant_problems`)."""
    bad, info = validity.variant_problems(recs, variants)
    return findings(bad), findings(info)


def validate_records(
    recs: Sequence[dict[str, Any]],
    bad: Sequence[records.Unreadable],
    allow_unverified: bool = False,
) -> list[Finding]:
    """The gating findings of :func:`hnnbench._results.validity.validate_each`: the
    files left out, each record on its own, the tuning budgets."""
    return findings(validity.validate_each(recs, bad, allow_unverified=allow_unverified).problems)


def budget_findings(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """Unequal tuning budgets (:func:`hnnbench._results.validity.budget_problems`)."""
    return findings(validity.budget_problems(recs))


def plugin_information(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """Plugin packages of another (non-null) version than the installed one: shown, not
    failing (the plugin's own ``version`` says when its results change)."""
    out = []
    for rec in recs:
        out += findings(validity.record_problems(rec)[1])
    return out
