"""The one strict validation of a set of records, for every door a record enters by
(``hnnbench check`` and ``check --update``, ``report --strict``, ``hnnbench.load(strict=
True)``, publishing): docs/LEADERBOARD.md, "Threat model".

On top of the strict loader (:func:`hnnbench._record.loader.load`: the schema, each
record's fields against each other, duplicate JSON keys, interpolations), it checks:

- **provenance**: the fields every record must name, its plugin versions and packages
  against the installed ones (:func:`hnnbench._results.provenance.plugin_problems`);
- **derived, not declared**: ``family``, ``backend``, ``ranked`` and ``reference`` from
  the installed model's class, the track from the stored config
  (:func:`hnnbench._record.tracks.track_problem`), the variant from the stored config
  (:func:`hnnbench._results.provenance.config_variant`);
- **verifiable plugins**: a plugin that is not installed, unusable (an import that
  failed, a name claimed by two distributions) or a record without ``plugins`` cannot be
  verified: a failure unless the caller allows it (``--allow-unverified``), and then
  said;
- **complete rows**: every seed of a row carries every metric another seed of the row
  carries;
- **equal tuning budgets** across a system's tuned models.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._record.fields import PROVENANCE_FIELDS
from hnnbench._record.tracks import track_of, track_problem
from hnnbench._record.validation import variant_problem
from hnnbench._results import provenance
from hnnbench._results.leaderboard import variant_labels, variant_overrides

__all__ = [
    "ALLOW_UNVERIFIED",
    "InvalidRecords",
    "Problem",
    "Validation",
    "budget_problems",
    "derived_problems",
    "record_variants",
    "require_valid",
    "row_problems",
    "unverified_problems",
    "validate",
    "validate_each",
    "variant_problems",
]

#: The flag that lets records of plugins that cannot be verified pass (said in output).
ALLOW_UNVERIFIED = "--allow-unverified"


class InvalidRecords(HnnbenchError):
    """Records that did not pass the strict validation (one line: the first, and how
    many)."""


@dataclass
class Problem:
    """One finding about the records, in the columns of ``hnnbench check``'s table."""

    check: str
    metric: str
    system: str
    model: str
    reference: str
    current: str
    factor: str = ""
    limit: str = ""

    def line(self) -> str:
        """One line: which record, what is wrong, and what was expected."""
        head = self.model if self.system == "-" else f"{self.system}/{self.model}"
        told = "; ".join(part for part in (self.reference, self.current) if part)
        expected = f" (expected {self.limit})" if self.limit and self.limit != "-" else ""
        return f"{self.check}: {head}: {told}{expected}"


@dataclass
class Validation:
    """What :func:`validate` found: ``problems`` fail; ``information`` does not;
    ``unverified``: records whose plugins could not be verified (in ``problems`` unless
    allowed, else in ``information``)."""

    problems: list[Problem] = field(default_factory=list)
    information: list[Problem] = field(default_factory=list)
    unverified: list[Problem] = field(default_factory=list)
    allowed_unverified: bool = False

    @property
    def ok(self) -> bool:
        return not self.problems


def record_file(rec: dict[str, Any]) -> str:
    return str(Path(rec["path"]) / records.RECORD_NAME) if rec.get("path") else "?"


def _names(rec: dict[str, Any]) -> tuple[str, str, str]:
    return str(rec.get("system")), str(rec.get("model")), record_file(rec)


def record_variants(recs: Sequence[dict[str, Any]]) -> list[provenance.Variant]:
    """Each record's variant, derived from its stored config and the defaults of its
    profile (:func:`hnnbench._results.provenance.config_variant`); where that cannot be
    done, the label its overrides claim."""
    claimed = variant_labels([variant_overrides(rec) for rec in recs])
    return [provenance.config_variant(rec, label) for rec, label in zip(recs, claimed, strict=True)]


def _installed(kind: str, name: str) -> Any:
    info = registry.discover(kind).get(name)  # type: ignore[arg-type]
    return info


def unverified_problems(rec: dict[str, Any]) -> list[Problem]:
    """Why ``rec``'s plugins cannot be verified here: not installed, unusable (its import
    failed, or two distributions claim its name), or the record names no ``plugins``."""
    system, model, where = _names(rec)
    out = []
    for kind in provenance.KINDS:
        name = str(rec.get(kind))
        info = _installed(kind, name)
        if info is None:
            why = f"the {kind} plugin '{name}' is not installed here"
        elif not info.ok:
            why = f"the {kind} plugin '{name}' is unusable here ({info.error})"
        else:
            continue
        out.append(
            Problem(
                "unverified", kind, system, model, where, why, "", "install the plugin it names"
            )
        )
    if not isinstance(rec.get("plugins"), dict):
        out.append(
            Problem(
                "unverified",
                "plugins",
                system,
                model,
                where,
                "the record names no plugins (their versions and packages)",
                "",
                "a record written by hnnbench >= 0.3",
            )
        )
    return out


def derived_problems(rec: dict[str, Any]) -> list[Problem]:
    """``family``, ``backend``, ``ranked`` and ``reference`` of ``rec`` against what the
    installed model's class declares (nothing to compare where it is not installed:
    :func:`unverified_problems` says so)."""
    system, model, where = _names(rec)
    info = _installed("model", model)
    if info is None or not info.ok:
        return []
    cls = info.cls
    family = getattr(getattr(cls, "family", None), "name", None)
    derived = {
        "family": family,
        "backend": getattr(cls, "backend", None),
        "ranked": bool(getattr(cls, "ranked", True)),
        "reference": getattr(cls, "reference", None),
    }
    out = []
    for key, want in derived.items():
        if key not in rec and key != "backend":
            continue  # an older record that did not say: derived, never read
        have = rec.get(key)
        if have != want or type(have) is not type(want):
            out.append(
                Problem(
                    "derived",
                    key,
                    system,
                    model,
                    where,
                    f"the record says {key} {have!r}, the installed {model} is {want!r}",
                    "",
                    "what the installed model declares",
                )
            )
    return out


def variant_problems(
    recs: Sequence[dict[str, Any]], variants: Sequence[provenance.Variant]
) -> tuple[list[Problem], list[Problem]]:
    """``(problems, information)`` about the records' variants: a setting that differs
    from the profile's defaults with no override saying so, a config of another job
    than the record's, a config that cannot be compared (no config: a problem; a plugin
    not installed: information, since :func:`unverified_problems` gates it), a variant
    label that is not of safe ``key=value`` tokens."""
    bad: list[Problem] = []
    info: list[Problem] = []
    for rec, variant in zip(recs, variants, strict=True):
        system, model, where = _names(rec)
        unsafe = variant_problem(variant.label)
        if unsafe:
            bad.append(Problem("variant", "config", system, model, where, unsafe))
        if variant.mismatch:
            bad.append(
                Problem(
                    "variant",
                    "config",
                    system,
                    model,
                    where,
                    f"its config is of another job ({variant.mismatch})",
                )
            )
        if variant.problem:
            finding = Problem("variant", "config", system, model, where, str(variant.problem))
            (bad if variant.installed else info).append(finding)
        elif variant.undeclared:
            text = variant.undeclared_text(str(rec.get("profile") or "paper"))
            bad.append(Problem("variant", variant.undeclared[0], system, model, where, text))
    return bad, info


def _field(rec: dict[str, Any], name: str) -> Any:
    value: Any = rec
    for part in name.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    return value


def record_problems(rec: dict[str, Any]) -> tuple[list[Problem], list[Problem]]:
    """``(problems, information)`` of one record: missing provenance, plugin versions or
    packages that differ from the installed ones, its track against its config and
    tuning, its derived fields."""
    system, model, where = _names(rec)
    bad: list[Problem] = []
    info: list[Problem] = []
    missing = [name for name in PROVENANCE_FIELDS if not _field(rec, name)]
    if missing:
        bad.append(
            Problem("provenance", "-", system, model, where, f"missing {', '.join(missing)}")
        )
    for key, mine, have, gate in provenance.plugin_problems(rec):
        (bad if gate else info).append(
            Problem(
                "version",
                key,
                system,
                model,
                f"record {mine}",
                f"installed {have}",
                "",
                f"same plugin ({where})" if gate else "information",
            )
        )
    problem = track_problem(rec)
    if problem is not None:
        bad.append(Problem("track", "-", system, model, where, problem))
    bad += derived_problems(rec)
    return bad, info


def budget_problems(recs: Sequence[dict[str, Any]]) -> list[Problem]:
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
                Problem(
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


def _present(value: Any) -> bool:
    mean = value.get("mean") if isinstance(value, dict) else None
    return isinstance(mean, (int, float)) and not isinstance(mean, bool) and not math.isnan(mean)


def row_problems(
    recs: Sequence[dict[str, Any]], labels: Optional[Sequence[str]] = None
) -> list[Problem]:
    """Complete rows: within each row (profile, system, model, variant, track), every
    ``ok`` seed carries every metric another ``ok`` seed carries (a missing or ``null``
    value is not averaged out of the row's mean; a row of one seed is held to the
    reference by ``compare``, where a value the reference has and the row lacks fails)."""
    labels = labels if labels is not None else [""] * len(recs)
    rows: dict[tuple[str, ...], list[dict[str, Any]]] = {}
    out: list[Problem] = []
    for rec, label in zip(recs, labels, strict=True):
        if rec.get("status") != "ok":
            continue
        key = (
            str(rec.get("profile")),
            str(rec.get("system")),
            str(rec.get("model")),
            label,
            track_of(rec),
        )
        rows.setdefault(key, []).append(rec)
    for group in rows.values():
        if len(group) < 2:
            continue
        carried = {
            name
            for rec in group
            for name, value in (rec.get("metrics") or {}).items()
            if _present(value)
        }
        for rec in group:
            metrics = rec.get("metrics") or {}
            lacking = sorted(name for name in carried if not _present(metrics.get(name)))
            if lacking:
                system, model, where = _names(rec)
                others = sorted(
                    str(r.get("seed"))
                    for r in group
                    if _present((r.get("metrics") or {}).get(lacking[0]))
                )
                out.append(
                    Problem(
                        "incomplete",
                        lacking[0],
                        system,
                        model,
                        where,
                        f"seed {rec.get('seed')} has no value of {lacking[0]} but seeds "
                        f"{','.join(others)} of its row do"
                        + (f" (and {len(lacking) - 1} more metric(s))" if len(lacking) > 1 else ""),
                        "",
                        "every seed of a row carries every metric it applies to",
                    )
                )
    return out


def validate_each(
    recs: Sequence[dict[str, Any]],
    bad: Sequence[records.Unreadable] = (),
    *,
    allow_unverified: bool = False,
) -> Validation:
    """The files a load left out, each record on its own (:func:`record_problems`,
    :func:`unverified_problems`) and the tuning budgets; :func:`validate` adds the
    variants and complete rows."""
    out = Validation(allowed_unverified=allow_unverified)
    for item in bad:
        kind = "invalid" if item.reason.startswith("invalid") else "unreadable"
        out.problems.append(Problem(kind, "-", "-", str(item.path), "", item.reason))
    for rec in recs:
        problems, info = record_problems(rec)
        out.problems += problems
        out.information += info
        unverified = unverified_problems(rec)
        out.unverified += unverified
        (out.information if allow_unverified else out.problems).extend(unverified)
    out.problems += budget_problems(recs)
    return out


def validate(
    recs: Sequence[dict[str, Any]],
    bad: Sequence[records.Unreadable] = (),
    *,
    variants: Optional[Sequence[provenance.Variant]] = None,
    allow_unverified: bool = False,
) -> Validation:
    """Everything the records of a strict load are held to (see the module docstring),
    and the files the load left out. ``variants``: :func:`record_variants` of ``recs``,
    if already derived."""
    out = validate_each(recs, bad, allow_unverified=allow_unverified)
    variants = list(variants) if variants is not None else record_variants(recs)
    variant_bad, variant_info = variant_problems(recs, variants)
    out.problems += variant_bad + row_problems(recs, [v.label for v in variants])
    out.information += variant_info
    return out


def require_valid(
    recs: Sequence[dict[str, Any]],
    bad: Sequence[records.Unreadable] = (),
    *,
    door: str,
    allow_unverified: bool = False,
) -> Validation:
    """:func:`validate`, raising :class:`InvalidRecords` (one line: the first problem,
    how many, and what to do) unless every record passed."""
    checked = validate(recs, bad, allow_unverified=allow_unverified)
    if checked.problems:
        first = checked.problems[0]
        more = len(checked.problems) - 1
        hint = (
            f"; pass {ALLOW_UNVERIFIED} to accept records whose plugins cannot be verified"
            if first.check == "unverified"
            else "; hnnbench check lists every one"
        )
        raise InvalidRecords(
            f"{door}: {first.line()}" + (f" (and {more} more problem(s))" if more else "") + hint
        )
    return checked
