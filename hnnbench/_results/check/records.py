"""The checked records themselves: readable and valid, with provenance, current plugin
versions, a variant derived from their stored config, equal tuning budgets.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hnnbench import _record as records
from hnnbench._record.fields import PROVENANCE_FIELDS
from hnnbench._record.tracks import track_of, track_problem
from hnnbench._record.validation import variant_problem
from hnnbench._results import provenance
from hnnbench._results.check.findings import Finding
from hnnbench._results.leaderboard import (
    variant_labels,
    variant_overrides,
)

__all__ = [
    "budget_findings",
    "plugin_information",
    "record_variants",
    "validate_records",
    "variant_findings",
]


def record_variants(recs: Sequence[dict[str, Any]]) -> list[provenance.Variant]:
    """Each record's variant, derived from its stored config and the defaults of its
    profile (:func:`hnnbench._results.provenance.config_variant`); where that cannot be done,
    the label its overrides claim (:func:`hnnbench._results.leaderboard.variant_labels`)."""
    claimed = variant_labels([variant_overrides(rec) for rec in recs])
    return [provenance.config_variant(rec, label) for rec, label in zip(recs, claimed, strict=True)]


def record_file(rec: dict[str, Any]) -> str:
    return str(Path(rec["path"]) / records.RECORD_NAME) if rec.get("path") else "?"


def variant_findings(
    recs: Sequence[dict[str, Any]], variants: Sequence[provenance.Variant]
) -> tuple[list[Finding], list[Finding]]:
    """``(regressions, information)`` about the records' variants: a setting that
    differs from the profile's defaults with no override saying so, a config of another
    job than the record's, a config that cannot be compared (no config: a regression;
    a plugin not installed here: information), a variant label that is not of safe
    ``key=value`` tokens (:data:`hnnbench._record.validation.VARIANT_TOKEN_PATTERN`)."""
    bad: list[Finding] = []
    info: list[Finding] = []
    for rec, variant in zip(recs, variants, strict=True):
        system, model, where = str(rec.get("system")), str(rec.get("model")), record_file(rec)
        unsafe = variant_problem(variant.label)
        if unsafe:
            bad.append(Finding("variant", "config", system, model, where, unsafe))
        if variant.mismatch:
            bad.append(
                Finding(
                    "variant",
                    "config",
                    system,
                    model,
                    where,
                    f"its config is of another job ({variant.mismatch})",
                )
            )
        if variant.problem:
            finding = Finding("variant", "config", system, model, where, str(variant.problem))
            (bad if variant.installed else info).append(finding)
        elif variant.undeclared:
            text = variant.undeclared_text(str(rec.get("profile") or "paper"))
            bad.append(Finding("variant", variant.undeclared[0], system, model, where, text))
    return bad, info


def _field(rec: dict[str, Any], name: str) -> Any:
    """The value of ``name`` in ``rec`` (``a.b``: key ``b`` of field ``a``), or ``None``."""
    value: Any = rec
    for part in name.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    return value


def validate_records(
    recs: Sequence[dict[str, Any]], bad: Sequence[records.Unreadable]
) -> list[Finding]:
    """Findings about the records themselves: unreadable files, schema violations (the
    records of a strict :func:`hnnbench._record.loader.load`, and the files it left out),
    missing provenance, plugin versions or packages that differ from the installed ones
    (:func:`hnnbench._results.provenance.plugin_problems`; a missing version is a mismatch).
    The gating ones; :func:`plugin_information` has the others."""
    out = [
        Finding(
            "invalid" if item.reason.startswith("invalid") else "unreadable",
            "-",
            "-",
            str(item.path),
            "",
            item.reason,
        )
        for item in bad
    ]
    for rec in recs:
        where = str(rec.get("path", "?"))
        system, model = str(rec.get("system")), str(rec.get("model"))
        missing = [name for name in PROVENANCE_FIELDS if not _field(rec, name)]
        if missing:
            out.append(
                Finding("provenance", "-", system, model, where, f"missing {', '.join(missing)}")
            )
        for key, mine, have, gate in provenance.plugin_problems(rec):
            if gate:
                out.append(
                    Finding(
                        "version",
                        key,
                        system,
                        model,
                        f"record {mine}",
                        f"installed {have}",
                        "",
                        f"same plugin ({where})",
                    )
                )
        problem = track_problem(rec)
        if problem is not None:
            out.append(Finding("track", "-", system, model, where, problem))
    return out + budget_findings(recs)


def budget_findings(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """The tuned track's promise, checked: on each (profile, system), every tuned model
    had the same number of trials, each of the same step budget on the same number of
    seeds (docs/TUNING.md; records before ``seeds_per_trial``: one seed)."""
    budgets: dict[tuple[str, str], dict[tuple[Any, Any, Any], set[str]]] = {}
    for rec in recs:
        tuning = rec.get("tuning")
        if track_of(rec) != "tuned" or not isinstance(tuning, dict):
            continue
        pair = (str(rec.get("profile")), str(rec.get("system")))
        budget = (tuning.get("trials"), tuning.get("steps"), tuning.get("seeds_per_trial", 1))
        budgets.setdefault(pair, {}).setdefault(budget, set()).add(str(rec.get("model")))
    out = []
    for (profile, system), found in budgets.items():
        if len(found) > 1:
            shown = "; ".join(
                f"{t} trials x {s} steps x {n} seed(s): {', '.join(sorted(models))}"
                for (t, s, n), models in found.items()
            )
            out.append(
                Finding(
                    "budget",
                    "-",
                    system,
                    "tuned track",
                    f"{profile} profile",
                    f"unequal tuning budgets ({shown})",
                    "",
                    "the same trials, steps and seeds per trial for every model",
                )
            )
    return out


def plugin_information(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """Plugin packages of another (non-null) version than the installed one: shown, not
    failing (the plugin's own ``version`` says when its results change)."""
    out = []
    for rec in recs:
        for key, mine, have, gate in provenance.plugin_problems(rec):
            if not gate:
                out.append(
                    Finding(
                        "version",
                        key,
                        str(rec.get("system")),
                        str(rec.get("model")),
                        f"record {mine}",
                        f"installed {have}",
                        "",
                        "information",
                    )
                )
    return out
