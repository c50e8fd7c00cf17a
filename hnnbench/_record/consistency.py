"""A record's fields checked against each other (docs/LEADERBOARD.md, "Threat model"):
the training log against the selected checkpoint and the criterion it names, the steps
against the training protocol and the stored config, each metric within the bound its
system sets (a time along the rollout at most the evaluation horizon), and no
interpolation (``${...}``) in the stored config or overrides. Each schema version is
read by its own rule (:data:`RULES`): a record written before a change is held to what
it could say then, never waved through unchecked.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Optional

from hnnbench._contracts.names import shown_key, shown_value
from hnnbench._contracts.plugin import (
    HISTORY_STEP,
    HISTORY_VALID,
    SELECTION_RULE,
    SELECTION_Z,
    SystemConfig,
)

__all__ = [
    "LEGACY_SELECTION_RULE",
    "RULES",
    "SchemaRule",
    "consistency_problems",
    "interpolation_problems",
    "rule_of",
]

#: The selection rule of records of schema versions 1 and 2: the checkpoint of the
#: lowest validation loss (``selection.rule``).
LEGACY_SELECTION_RULE = "lowest validation loss over the evaluations"
#: The test loss's column in a schema-1 record's training log (later logs have none).
LEGACY_HISTORY_TEST = "test_loss"
#: How far apart two copies of one float may be (the record's JSON round trip is exact;
#: this only absorbs a plugin's float32 losses printed through float64).
REL_TOL = 1e-9


@dataclass(frozen=True)
class SchemaRule:
    """How records of one schema version are read.

    Attributes:
        version: the ``schema_version``.
        name: the rule, named in every message about it.
        selection_rules: the ``selection.rule`` texts a record of this version may carry.
        history_losses: the training log's validation-loss columns, in order of
            preference (schema 1 logged the test loss before the validation split).
    """

    version: int
    name: str
    selection_rules: tuple[str, ...]
    history_losses: tuple[str, ...]


#: Every schema version's rule. Versions 1 and 2 are legacy: their records selected the
#: checkpoint of the lowest validation loss; version 3 selects the final checkpoint
#: unless an earlier one wins by :data:`~hnnbench._contracts.plugin.SELECTION_Z` paired
#: standard errors (docs/METRICS.md, "Checkpoint selection").
RULES: Mapping[int, SchemaRule] = {
    1: SchemaRule(
        1,
        "legacy rule of schema 1",
        (LEGACY_SELECTION_RULE,),
        (HISTORY_VALID, LEGACY_HISTORY_TEST),
    ),
    2: SchemaRule(2, "legacy rule of schema 2", (LEGACY_SELECTION_RULE,), (HISTORY_VALID,)),
    3: SchemaRule(3, "rule of schema 3", (SELECTION_RULE,), (HISTORY_VALID,)),
}


def rule_of(record: Mapping[str, Any]) -> Optional[SchemaRule]:
    """The rule of ``record``'s schema version (``None``: a version no rule reads; the
    schema names it)."""
    version = record.get("schema_version")
    return RULES.get(version) if isinstance(version, int) else None


def _strings(value: Any, where: str) -> Iterator[tuple[str, str]]:
    """Every string (keys too) of ``value`` with where it is, without recursion."""
    stack: list[tuple[Any, str]] = [(value, where)]
    while stack:
        item, at = stack.pop()
        if isinstance(item, str):
            yield at, item
        elif isinstance(item, dict):
            for key, inner in item.items():
                yield f"{at}.{shown_key(key)}", str(key)
                stack.append((inner, f"{at}.{shown_key(key)}"))
        elif isinstance(item, list):
            stack.extend((inner, f"{at}.{i}") for i, inner in enumerate(item))


def interpolation_problems(record: Mapping[str, Any]) -> list[str]:
    """A ``${...}`` interpolation in the stored ``config`` or ``overrides``: a record's
    text is never resolved (it could read the reader's environment or files), so such a
    record is refused on load."""
    for name in ("config", "overrides"):
        for where, text in _strings(record.get(name), name):
            if "${" in text:
                return [
                    f"{where}: {shown_value(text)} holds an interpolation ('${{...}}'); "
                    "a record stores resolved values only, and none is resolved on "
                    "reading: re-run the job to write its record"
                ]
    return []


def _num(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def _close(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b or math.isclose(a, b, rel_tol=REL_TOL, abs_tol=0.0)


def _steps_problems(record: Mapping[str, Any]) -> list[str]:
    """``steps`` against ``train`` (the protocol), and ``train`` against the stored
    config (the model's setting, else the system's)."""
    train, config = record.get("train"), record.get("config")
    steps = record.get("steps")
    if not isinstance(train, dict):
        return []
    if isinstance(config, dict):
        system, model = config.get("system"), config.get("model")
        if isinstance(system, dict) and isinstance(model, dict):
            for key in SystemConfig.TRAINING_FIELDS:
                if key not in train or key not in system:
                    continue
                want = model.get(key) if model.get(key) is not None else system.get(key)
                if train[key] != want or type(train[key]) is not type(want):
                    return [
                        f"train.{key}: {shown_value(train[key])} is not the stored config's "
                        f"{shown_value(want)} (config.model.{key}, else config.system.{key})"
                    ]
    planned = train.get("steps")
    if isinstance(steps, int) and isinstance(planned, int) and record.get("status") != "skipped":
        stopped = isinstance(record.get("selection"), dict) and record["selection"].get("stopped")
        # A model without an iterative training loop (a fit in closed form, the
        # references) logs no step and reports the steps it counts (FitResult.steps).
        history = record.get("history")
        iterative = isinstance(history, dict) and bool(history.get(HISTORY_STEP))
        if steps > planned or (iterative and steps != planned and not stopped):
            return [
                f"steps: {steps} is not the protocol's train.steps {planned} (fewer only "
                "when selection.stopped says why)"
            ]
    return []


def _history_problems(record: Mapping[str, Any]) -> list[str]:
    history, steps = record.get("history"), record.get("steps")
    if not isinstance(history, dict):
        return []
    logged = history.get(HISTORY_STEP)
    if not isinstance(logged, list):
        return []
    for key, values in history.items():
        if isinstance(values, list) and len(values) != len(logged):
            return [
                f"history.{shown_key(key)}: {len(values)} values for {len(logged)} "
                "logged steps (one per step)"
            ]
    numbers = [_num(s) for s in logged]
    if any(not (b > a) for a, b in zip(numbers, numbers[1:], strict=False)):
        return ["history.step: the logged steps do not increase"]
    if numbers and isinstance(steps, int) and numbers[-1] > steps:
        return [f"history.step: step {logged[-1]} logged beyond the {steps} steps taken"]
    return []


def _selection_problems(record: Mapping[str, Any], rule: SchemaRule) -> list[str]:
    """``selection`` against the training log and against the rule it names."""
    sel, history = record.get("selection"), record.get("history")
    if not isinstance(sel, dict) or not isinstance(history, dict):
        return []
    if sel.get("rule") not in rule.selection_rules:
        return [
            f"selection.rule: {shown_value(sel.get('rule'))} is not the selection rule of "
            f"a schema {rule.version} record ({rule.name}: {rule.selection_rules[0]!r})"
        ]
    logged = history.get(HISTORY_STEP)
    column = next((history[k] for k in rule.history_losses if k in history), None)
    if not isinstance(logged, list) or not isinstance(column, list) or not logged:
        return ["selection: the record selects a checkpoint but holds no training log"]
    losses = {s: _num(v) for s, v in zip(logged, column, strict=False)}

    def at(step_key: str, value_key: str) -> Optional[str]:
        step = sel.get(step_key)
        if step not in losses:
            return f"selection.{step_key}: {shown_value(step)} is not a logged step"
        if not _close(losses[step], _num(sel.get(value_key))):
            return (
                f"selection.{value_key}: {shown_value(sel.get(value_key))} is not the "
                f"logged {HISTORY_VALID} {losses[step]!r} at step {step}"
            )
        return None

    problem = at("step", "validation_loss")
    if problem:
        return [problem]
    if sel.get("evaluations") != len(logged):
        return [
            f"selection.evaluations: {shown_value(sel.get('evaluations'))} is not the "
            f"{len(logged)} logged evaluations"
        ]
    if sel.get("first_step") != logged[0]:
        return [
            f"selection.first_step: {shown_value(sel.get('first_step'))} is not the first "
            f"logged step {logged[0]}"
        ]
    if "trained" in sel and sel["trained"] != (_num(sel["step"]) > _num(logged[0])):
        return [f"selection.trained: {sel['trained']} contradicts step {sel['step']}"]
    finite = [v for v in losses.values() if math.isfinite(v)]
    lowest = min(finite) if finite else math.nan
    if sel["rule"] == LEGACY_SELECTION_RULE:
        if not _close(_num(sel["validation_loss"]), lowest):
            return [
                f"selection.validation_loss: {sel['validation_loss']!r} is not the lowest "
                f"logged {HISTORY_VALID} {lowest!r}, as its rule ({LEGACY_SELECTION_RULE}) says"
            ]
        return []
    if sel.get("best_step") is None:
        return []  # a plugin's own loop: no criterion's checkpoints recorded
    problem = at("best_step", "best_value") or at("final_step", "final_value")
    if problem:
        return [problem]
    if not _close(_num(sel["best_value"]), lowest):
        return [
            f"selection.best_value: {sel['best_value']!r} is not the lowest logged "
            f"{HISTORY_VALID} {lowest!r}"
        ]
    best, final = _num(sel["best_value"]), _num(sel["final_value"])
    se = _num(sel.get("final_se"))
    earlier = sel["best_step"] != sel["final_step"] and (
        not math.isfinite(se) or final - best > SELECTION_Z * se
    )
    allowed = {sel["best_step"] if earlier else sel["final_step"]}
    if sel.get("stopped"):
        allowed.add(sel["best_step"])  # after a non-finite loss the lowest is scored
    if sel["step"] not in allowed:
        return [
            f"selection.step: {sel['step']} is not the checkpoint its rule picks "
            f"({sorted(allowed)[0]}: {SELECTION_RULE})"
        ]
    return []


def _bound_problems(
    record: Mapping[str, Any], horizon_metrics: Callable[[], frozenset[str]]
) -> list[str]:
    """Each metric declared a time along the evaluation rollout at most the horizon the
    record's evaluation data states (``data.evaluation_meta.horizon``)."""
    data = record.get("data")
    meta = data.get("evaluation_meta") if isinstance(data, dict) else None
    horizon = _num(meta.get("horizon")) if isinstance(meta, dict) else math.nan
    metrics = record.get("metrics")
    if not math.isfinite(horizon) or not isinstance(metrics, dict):
        return []
    for name in sorted(horizon_metrics()):
        value = metrics.get(name)
        mean = _num(value.get("mean")) if isinstance(value, dict) else math.nan
        if math.isfinite(mean) and mean > horizon * (1 + REL_TOL):
            return [
                f"metrics.{name}: mean {mean!r} is beyond the evaluation horizon "
                f"{horizon!r} (data.evaluation_meta.horizon), its largest value"
            ]
    return []


def consistency_problems(
    record: Mapping[str, Any],
    horizon_metrics: Callable[[], frozenset[str]] = frozenset,
) -> list[str]:
    """What contradicts itself in ``record`` (decoded), one line each (empty: none),
    read by its schema version's rule (:data:`RULES`). ``horizon_metrics``: the names
    of the metrics declared bounded by the evaluation horizon."""
    rule = rule_of(record)
    if rule is None:
        return []  # the schema names the version
    return (
        _steps_problems(record)
        or _history_problems(record)
        or _selection_problems(record, rule)
        or _bound_problems(record, horizon_metrics)
    )
