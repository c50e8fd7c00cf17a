"""What a record is held to (docs/LEADERBOARD.md, "Threat model"): the JSON Schema
(on write and in a strict load), the quick shape check of every load, the training
history's values, variant labels, ``created_at``, each metric's declared domain.
"""

from __future__ import annotations

import datetime as _dt
import math
import re
from collections.abc import Callable, Mapping
from functools import lru_cache
from typing import Any, Optional

from hnnbench._contracts.names import LOADER_FIELDS, pattern_matches, shown_key, shown_value
from hnnbench._record.codec import depth_problems, encode
from hnnbench._record.consistency import consistency_problems, interpolation_problems
from hnnbench._record.fields import FIELDS, REQUIRED, json_schema

__all__ = [
    "FUTURE_SKEW",
    "STRICT_CHECKS",
    "VARIANT_TOKEN_PATTERN",
    "created_at_problem",
    "created_at_problems",
    "field_consistency_problems",
    "history_problems",
    "is_date_time",
    "metric_domain_problems",
    "schema",
    "shape_problems",
    "strict_problems",
    "validate",
    "variant_problem",
]


#: One token of a variant label (``model.hidden=200``): a dotted setting, ``=``, and a
#: value of safe characters (numbers, words, JSON lists and mappings without spaces);
#: no path separator, no Markdown or HTML markup, no line break.
VARIANT_TOKEN_PATTERN = '^[A-Za-z_][A-Za-z0-9_.]{0,127}=[A-Za-z0-9_.,:+\\-\\[\\]{}"]{0,128}$'
#: How far in the future (the reader's clock) a ``created_at`` may be: clocks differ.
FUTURE_SKEW = _dt.timedelta(hours=1)
_TYPES: dict[str, Any] = {
    "object": dict,
    "array": list,
    "string": str,
    "boolean": bool,
    "null": type(None),
}


def _is(value: Any, kind: str) -> bool:
    if kind == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, _TYPES[kind])


def _value_problem(where: str, value: Any, schema: Mapping[str, Any]) -> Optional[str]:
    kinds = schema.get("type")
    if kinds is not None:
        kinds = [kinds] if isinstance(kinds, str) else list(kinds)
        if not any(_is(value, k) for k in kinds):
            return f"{where}: {shown_value(value)} is not of type {', '.join(map(repr, kinds))}"
    if "enum" in schema and value not in schema["enum"]:
        return f"{where}: {shown_value(value)} is not one of {list(schema['enum'])!r}"
    if (
        isinstance(value, str)
        and "pattern" in schema
        and not pattern_matches(schema["pattern"], value)
    ):
        return f"{where}: {shown_value(value)} does not match {schema['pattern']!r}"
    return None


def _item_problem(where: str, value: Any, schema: Mapping[str, Any]) -> Optional[str]:
    """:func:`_value_problem`, and that of each declared property of an object."""
    problem = _value_problem(where, value, schema)
    if problem is None and isinstance(value, dict):
        for key, inner in (schema.get("properties") or {}).items():
            if key in value and (
                problem := _value_problem(f"{where}.{shown_key(key)}", value[key], inner)
            ):
                break
    return problem


def shape_problems(record: Mapping[str, Any]) -> list[str]:
    """What makes ``record`` (decoded JSON) unusable as a record, one line each naming
    the field (empty: usable): a missing required field, or a declared field of the
    wrong JSON type, outside its ``enum`` or not matching its ``pattern`` (a name that is
    not :data:`NAME_PATTERN`), checked two levels deep (so each metric is an object of
    values, each timing a number, each override a string). A quick check, for every
    record loaded; the full JSON Schema is checked on write and by strict loading
    (``hnnbench._record``)."""
    out = [
        f"'{f.name}' is a required property"
        for f in FIELDS
        if f.presence == REQUIRED and f.name not in record
    ]
    for f in FIELDS:
        if f.name not in record:
            continue
        value = record[f.name]
        problem = _value_problem(f.name, value, f.schema)
        if problem is None and isinstance(value, dict):
            inner = f.schema.get("additionalProperties")
            names = (f.schema.get("propertyNames") or {}).get("pattern")
            for key, item in value.items():
                if names and not pattern_matches(names, key):
                    problem = f"{f.name}: the key {shown_value(key)} does not match {names!r}"
                elif isinstance(inner, Mapping):
                    problem = _item_problem(f"{f.name}.{shown_key(key)}", item, inner)
                if problem is not None:
                    break
        if problem is None and f.name == "history":
            problem = next(iter(history_problems(value)), None)
        elif problem is None and isinstance(value, list):
            inner = f.schema.get("items")
            if isinstance(inner, Mapping):
                problem = next(
                    (
                        p
                        for i, item in enumerate(value)
                        if (p := _value_problem(f"{f.name}.{i}", item, inner))
                    ),
                    None,
                )
        if problem is not None:
            out.append(problem)
    return out or interpolation_problems(record)


#: What a training history's values may be (the schema's ``history`` items; bare NaN
#: and Infinity, as schema version 1 wrote them, are floats), checked by a loop: per-item
#: JSON Schema validation of a long history took seconds.
_HISTORY_TYPES = (int, float)
_HISTORY_STRINGS = ("inf", "-inf")


def history_problems(history: Any) -> list[str]:
    """The first problem of a record's ``history`` (an object of arrays of numbers,
    ``null``, ``"inf"`` or ``"-inf"``), one line naming the field; ``[]`` if none."""
    if not isinstance(history, dict):
        return [f"history: {shown_value(history)} is not of type 'object'"]
    for key, values in history.items():
        if not isinstance(values, list):
            return [f"history.{shown_key(key)}: {shown_value(values)} is not of type 'array'"]
        for i, value in enumerate(values):
            if (
                value is None
                or type(value) in _HISTORY_TYPES
                or (type(value) is str and value in _HISTORY_STRINGS)
            ):
                continue
            return [
                f"history.{shown_key(key)}.{i}: {shown_value(value)} is not a number, "
                "null, 'inf' or '-inf'"
            ]
    return []


def variant_problem(label: str) -> Optional[str]:
    """Why the variant label ``label`` (space-separated ``key=value`` tokens) is not one
    of safe tokens (:data:`VARIANT_TOKEN_PATTERN`), or ``None``."""
    if not isinstance(label, str) or len(label) > 4096:
        return f"the variant {shown_value(label)} is not a short text"
    for token in label.split(" ") if label else ():
        if not pattern_matches(VARIANT_TOKEN_PATTERN, token):
            return (
                f"the variant setting {shown_value(token)} is not key=value of safe "
                'characters (letters, digits, _ . , : + - [ ] { } ")'
            )
    return None


_DATE_TIME = re.compile(
    r"\d{4}-\d{2}-\d{2}[Tt]\d{2}:\d{2}:\d{2}(\.\d{1,9})?"
    r"([Zz]|[+-]\d{2}:\d{2})"
)


def _parse_date_time(text: str) -> Optional[_dt.datetime]:
    if not _DATE_TIME.fullmatch(text):
        return None
    norm = text.upper()
    norm = norm[:-1] + "+00:00" if norm.endswith("Z") else norm
    head, dot, rest = norm.partition(".")
    if dot:  # fromisoformat takes at most 6 fractional digits
        digits = rest[:-6]
        norm = f"{head}.{(digits + '000000')[:6]}{rest[-6:]}"
    try:
        return _dt.datetime.fromisoformat(norm)
    except ValueError:
        return None


def is_date_time(text: Any) -> bool:
    """Whether ``text`` is an RFC 3339 date-time (``2026-11-24T21:28:43+00:00``, ``...Z``,
    fractional seconds allowed; a real date and time with an explicit offset). The
    record schema's ``format: date-time``, enforced (``hnnbench._record``)."""
    return isinstance(text, str) and _parse_date_time(text) is not None


def created_at_problem(value: Any, now: Optional[_dt.datetime] = None) -> Optional[str]:
    """Why ``value`` cannot be a record's ``created_at``, or ``None``: an RFC 3339
    date-time (:func:`is_date_time`) not later than ``now`` (default: this clock) plus
    :data:`FUTURE_SKEW`."""
    when = _parse_date_time(value) if isinstance(value, str) else None
    if when is None:
        return f"created_at: {shown_value(value)} is not an RFC 3339 date-time"
    now = now if now is not None else _dt.datetime.now(_dt.timezone.utc)
    if when > now + FUTURE_SKEW:
        return f"created_at: {value} is in the future (now {now.isoformat(timespec='seconds')})"
    return None


def schema() -> dict[str, Any]:
    """The record's JSON Schema (:func:`hnnbench._record.fields.json_schema`; shipped
    as ``hnnbench/resources/record.schema.json``)."""
    return dict(_validator().schema)


@lru_cache(maxsize=1)
def _validator() -> Any:
    import jsonschema

    # The schema's "format" is enforced, by hnnbench's own check (jsonschema's needs an
    # optional package, and without it passes any string).
    formats = jsonschema.FormatChecker(formats=())
    formats.checks("date-time")(is_date_time)
    return jsonschema.Draft202012Validator(json_schema(), format_checker=formats)


def schema_problems(data: Any) -> list[str]:
    """The JSON Schema violations of encoded record data, one line each naming the
    field (``a.b: ...``; a missing field: ``'a' is a required property``). The training
    history is checked by a loop (:func:`~hnnbench._record.validation.history_problems`),
    the rest by jsonschema."""
    if not isinstance(data, dict):
        return [f"{type(data).__name__} is not of type 'object'"]
    validator = _validator()
    rest = {k: v for k, v in data.items() if k != "history"}
    out = []
    if not validator.is_valid(rest):
        for err in sorted(
            validator.iter_errors(rest), key=lambda e: list(map(str, e.absolute_path))
        ):
            where = ".".join(
                shown_key(p) if isinstance(p, str) else str(p) for p in err.absolute_path
            )
            message = " ".join(str(err.message).split())
            message = message if len(message) <= 300 else message[:297] + "..."
            out.append(f"{where}: {message}" if where else message)
    if "history" in data:
        out += history_problems(data["history"])
    return out


def validate(record: dict[str, Any]) -> list[str]:
    """Schema violations of ``record`` (one line each; empty: valid). Fields the loader
    adds (``path``, ``source``) are ignored."""
    data = encode({k: v for k, v in record.items() if k not in LOADER_FIELDS})
    return depth_problems(data) or schema_problems(data)


def created_at_problems(record: dict[str, Any]) -> list[str]:
    """``created_at`` an RFC 3339 date-time that is not in the future
    (:func:`hnnbench._record.validation.created_at_problem`)."""
    if "created_at" not in record:
        return []  # a required field: the schema names it
    problem = created_at_problem(record["created_at"])
    return [problem] if problem else []


def metric_domain_problems(record: dict[str, Any]) -> list[str]:
    """Each metric's mean within its declared domain and its sem a standard error
    (:meth:`hnnbench._contracts.metric.Metric.value_problem`); a metric no installed plugin
    declares is held to a standard error only."""
    from hnnbench import _registry as registry
    from hnnbench._contracts.metric import Metric

    declared = {m.name: m for m in registry.metrics()}
    for name, value in (record.get("metrics") or {}).items():
        if not isinstance(value, dict):
            continue  # the schema names it
        metric = declared.get(name) or Metric(name, "", lambda ctx: None)
        mean, sem = value.get("mean", math.nan), value.get("sem", math.nan)
        problem = metric.value_problem(
            math.nan if mean is None else mean, math.nan if sem is None else sem
        )
        if problem:
            return [f"metrics.{shown_key(name)}: {problem}"]
    return []


def _horizon_metrics() -> frozenset[str]:
    from hnnbench import _registry as registry

    return frozenset(m.name for m in registry.metrics() if m.within_horizon)


def field_consistency_problems(record: dict[str, Any]) -> list[str]:
    """Fields that contradict each other, read by the rule of the record's schema
    version (:func:`hnnbench._record.consistency.consistency_problems`)."""
    return consistency_problems(record, _horizon_metrics)


#: The checks of a strict load after the JSON Schema, in order (each: a decoded record
#: -> its problems, one line each).
STRICT_CHECKS: tuple[Callable[[dict[str, Any]], list[str]], ...] = (
    created_at_problems,
    metric_domain_problems,
    field_consistency_problems,
)


def decoded_problems(record: dict[str, Any]) -> list[str]:
    for check in STRICT_CHECKS:
        problems = check(record)
        if problems:
            return problems
    return []


def strict_problems(record: dict[str, Any]) -> list[str]:
    """What a strict :func:`load` finds wrong with ``record`` (decoded; one line each;
    empty: none): the JSON Schema (:func:`validate`), then the checks of
    :data:`STRICT_CHECKS`."""
    return validate(record) or decoded_problems(record)
