"""The run record (``result.json``) defined once: every field with its JSON Schema,
presence, initial value and meaning; a job's new record; the shipped JSON Schema
(docs/ARCHITECTURE.md, "The result record").
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hnnbench._contracts.names import (
    BOARD_KEY,
    DEFAULT_TRACK,
    DERIVED_COLUMNS,
    FAMILY_KEY,
    FRAME_COLUMNS,
    ID_COLUMNS,
    JOB_FIELDS,
    LOADER_FIELDS,
    NAME_PATTERN,
    REFERENCES,
    STATUSES,
    TRACKS,
)
from hnnbench._record.tracks import SELECTED_ON

__all__ = [
    "FIELDS",
    "FINISHED",
    "Field",
    "OPTIONAL",
    "PROVENANCE_FIELDS",
    "RECORD_NAME",
    "REQUIRED",
    "ROLLOUT_NAME",
    "SCHEMA_FILE",
    "SCHEMA_VERSION",
    "SCHEMA_VERSIONS",
    "VALUE",
    "VERSION_FIELDS",
    "WRITTEN",
    "json_schema",
    "new_record",
    "schema_text",
]


#: The version of the records this hnnbench writes, and the versions it reads.
SCHEMA_VERSION = 3
SCHEMA_VERSIONS = (1, 2, 3)
#: Whether a record has a field: every record of every schema version (the schema
#: requires it), every record a job writes now (older ones may lack it), or only where
#: it applies.
REQUIRED, WRITTEN, OPTIONAL = "required", "written", "optional"
_NONE = object()  # no initial value: the job supplies it
#: A metric's mean or sem: a number; ``null`` where undefined (NaN); the string ``inf``
#: or ``-inf`` where infinite (``pattern`` applies to strings only). Written inline, not
#: as a ``$ref``: a training history holds thousands of them, and the check of a
#: record on write and in strict loading stays a few milliseconds.
VALUE: Mapping[str, Any] = {"type": ["number", "null", "string"], "pattern": "^-?inf$"}
_STRING_OR_NULL: Mapping[str, Any] = {"type": ["string", "null"]}
#: Names joined by commas (a CPU's OpenBLAS kernel, numpy's SIMD targets): they go
#: into a child process's environment in ``check --rerun``.
_NAMES = "^[A-Za-z0-9_]{1,32}(,[A-Za-z0-9_]{1,32}){0,31}$"
_INT_OR_NULL: Mapping[str, Any] = {"type": ["integer", "null"], "minimum": 0}
#: Where a plugin came from (``plugins.system``, ``plugins.model``).
_PLUGIN: Mapping[str, Any] = {
    "type": "object",
    "required": ["name", "version", "distribution", "distribution_version"],
    "properties": {
        "name": {"type": "string"},
        "version": _STRING_OR_NULL,
        "distribution": _STRING_OR_NULL,
        "distribution_version": _STRING_OR_NULL,
    },
}


@dataclass(frozen=True)
class Field:
    """One field of a record."""

    name: str
    #: The JSON Schema of its value.
    schema: Mapping[str, Any]
    description: str
    #: :data:`REQUIRED`, :data:`WRITTEN` or :data:`OPTIONAL`.
    presence: str = OPTIONAL
    #: The value a new record starts with (a :data:`REQUIRED` or :data:`WRITTEN` field
    #: without one is given by the job: :func:`new_record`).
    initial: Any = _NONE

    @property
    def written(self) -> bool:
        """Whether every record a job writes now starts with it."""
        return self.presence in (REQUIRED, WRITTEN)


#: Every field of a record, in the order a job writes them (:func:`new_record`; the
#: optional ones are added where they apply).
FIELDS: tuple[Field, ...] = (
    Field(
        "schema_version",
        {"enum": list(SCHEMA_VERSIONS)},
        "the version of this format",
        REQUIRED,
        SCHEMA_VERSION,
    ),
    Field(
        "system",
        {"type": "string", "pattern": NAME_PATTERN},
        "the system's registered name",
        REQUIRED,
    ),
    Field("system_version", _STRING_OR_NULL, "the system plugin's version", REQUIRED, None),
    Field(
        "model",
        {"type": "string", "pattern": NAME_PATTERN},
        "the model's registered name",
        REQUIRED,
    ),
    Field("model_version", _STRING_OR_NULL, "the model plugin's version", REQUIRED, None),
    Field("backend", _STRING_OR_NULL, "the model's backend (torch, jax, numpy)", REQUIRED, None),
    Field("family", _STRING_OR_NULL, "the model family (e.g. hnn), grouping backends"),
    Field(
        "ranked",
        {"type": "boolean"},
        "false for references such as the oracle: shown, never ranked",
    ),
    Field(
        "reference",
        {"enum": [None, *REFERENCES]},
        "the role of a trivial reference (zero_field: standing still, which a leader "
        "must beat; true_field: the oracle), null for a competitor; absent in records "
        "before schema 3",
    ),
    Field(
        "plugins",
        {
            "type": "object",
            "required": ["system", "model"],
            "properties": {"system": _PLUGIN, "model": _PLUGIN},
        },
        "the packages that provided the system and the model: each plugin's name, its "
        "version, its distribution and the distribution's version (absent in records "
        "before 0.3)",
    ),
    Field(
        "seed",
        {"type": "integer", "minimum": 0},
        "the seed of data, evaluation and initial weights",
        REQUIRED,
    ),
    Field(
        "profile",
        {"type": "string", "pattern": NAME_PATTERN},
        "the profile (quick, paper)",
        REQUIRED,
    ),
    Field("status", {"enum": list(STATUSES)}, "the job's outcome", REQUIRED, "failed"),
    Field("error", _STRING_OR_NULL, "why the job is not ok", REQUIRED, None),
    Field(
        "metrics",
        {
            "type": "object",
            "propertyNames": {"pattern": NAME_PATTERN},
            "additionalProperties": {
                "type": "object",
                "required": ["mean", "sem"],
                "properties": {"mean": VALUE, "sem": VALUE},
            },
        },
        "{name: {mean, sem}} for every registered metric",
        REQUIRED,
        {},
    ),
    Field(
        "timings",
        {"type": "object", "additionalProperties": {"type": "number", "minimum": 0}},
        "wall and CPU seconds of the job's parts",
        REQUIRED,
        {},
    ),
    Field("steps", {"type": "integer", "minimum": 0}, "optimizer steps taken", REQUIRED, 0),
    Field("device", _STRING_OR_NULL, "the device used", WRITTEN, None),
    Field("cpu_pin", {"type": ["integer", "null"]}, "the CPU the job's process was pinned to"),
    Field(
        "train",
        {"type": ["object", "null"]},
        "the training protocol (null for a model without a training loop)",
    ),
    Field(
        "data",
        {"type": "object"},
        "cache hit, SHA-256 of the dataset and evaluation files, sizes, generator metadata",
        WRITTEN,
        {},
    ),
    Field(
        "history",
        {"type": "object", "additionalProperties": {"type": "array", "items": VALUE}},
        "the training log: step, train_loss, val_loss (test_loss in records before "
        "the validation split)",
    ),
    Field(
        "selection",
        {
            "type": "object",
            "required": ["step", "validation_loss", "evaluations", "first_step", "trained"],
            "properties": {
                "rule": {"type": "string"},
                "criterion": _STRING_OR_NULL,
                "step": {"type": "integer", "minimum": 0},
                "validation_loss": VALUE,
                "evaluations": {"type": "integer", "minimum": 0},
                "first_step": {"type": "integer", "minimum": 0},
                "trained": {"type": "boolean"},
                "stopped": _STRING_OR_NULL,
                "points": {"type": "integer", "minimum": 0},
                "best_step": _INT_OR_NULL,
                "best_value": VALUE,
                "final_step": _INT_OR_NULL,
                "final_value": VALUE,
                "final_se": VALUE,
                "late_step": _INT_OR_NULL,
                "late_value": VALUE,
                "late_se": VALUE,
                "converged": {"type": ["boolean", "null"]},
            },
        },
        "the scored checkpoint of a model that selects on validation: the criterion "
        "(schema 3; docs/METRICS.md, 'Checkpoint selection'), the scored step and its "
        "criterion value (validation_loss), the evaluations made, the first one's step, "
        "whether it trained past that (false: 'did not train'), why training stopped "
        "early; and the lowest, final and late (80%) checkpoints' values with the paired "
        "standard errors of final - lowest and late - final, and whether the criterion "
        "stopped improving over the last 20% of steps (converged)",
    ),
    Field("config", {"type": "object"}, "the fully resolved job config", REQUIRED),
    Field(
        "overrides",
        {"type": ["array", "null"], "items": {"type": "string"}},
        "Hydra's overrides",
        WRITTEN,
    ),
    Field("command", _STRING_OR_NULL, "the command line as typed", WRITTEN),
    Field(
        "rerun_command", _STRING_OR_NULL, "a single-run command that reproduces the job", WRITTEN
    ),
    Field(
        "environment",
        {
            "type": "object",
            "required": ["hnnbench", "python", "platform", "git_commit"],
            "properties": {
                "hnnbench": _STRING_OR_NULL,
                "git_commit": _STRING_OR_NULL,
                "blas_kernel": {"type": ["string", "null"], "pattern": _NAMES},
                "numpy_simd": {"type": ["string", "null"], "pattern": f"^$|{_NAMES}"},
            },
        },
        "versions, platform, machine, host, git commit, the OpenBLAS kernel and numpy's "
        "SIMD targets",
        REQUIRED,
    ),
    Field("created_at", {"type": "string", "format": "date-time"}, "UTC timestamp", REQUIRED),
    Field("weights_file", _STRING_OR_NULL, "the weights file the model wrote next to the record"),
    Field(
        "metric_errors",
        {"type": "object", "additionalProperties": {"type": "string"}},
        "metrics whose computation raised, and the message",
    ),
    Field(
        "seed_batch",
        {"type": "array", "items": {"type": "integer"}},
        "the seeds trained together with this one",
    ),
    Field(
        "track",
        {"enum": list(TRACKS)},
        "the benchmark track: protocol (each system's shared protocol), tuned (settings "
        "an equal-budget tuning selected on validation), recipe (a family paper's own "
        "recipe); absent in older records, which are protocol",
        WRITTEN,
        DEFAULT_TRACK,
    ),
    Field(
        "tuning",
        {
            "type": "object",
            "required": ["selected_on"],
            "properties": {
                "selected_on": {"enum": [SELECTED_ON]},
                "objective": {"type": "string"},
                "criterion": {"type": "string"},
                "seeds_per_trial": {"type": "integer", "minimum": 1},
                "trial_seeds": {"type": "array", "items": {"type": "integer", "minimum": 0}},
                "protocol_trial": {"type": ["integer", "null"], "minimum": 0},
                "protocol_value": VALUE,
                "score": {"type": "string"},
                "fold": _INT_OR_NULL,
                "cpu_s_per_trial": {"type": "number", "minimum": 0},
                "trials": {"type": "integer", "minimum": 1},
                "steps": {"type": "integer", "minimum": 1},
                "space": {"type": "object"},
                "selected": {"type": "object"},
                "selected_trial": {"type": ["integer", "null"], "minimum": 0},
                "selected_value": VALUE,
                "cpu_s": {"type": "number", "minimum": 0},
                "trial": {"type": "integer", "minimum": 0},
                "study": {"type": "string"},
            },
        },
        "how a tuned run's settings were chosen (hnnbench tune): the objective and "
        "that it was read on the validation split, the criterion (the system's "
        "selection criterion), the seeds of each trial and how their criteria make its "
        "score, the trial of the protocol's settings and its score, the fold of a "
        "measured system's study, the trials per model and the step budget of each, "
        "the search space, the selected settings, the CPU seconds of all trials and "
        "per trial; a trial's own record has its trial number instead of the "
        "selection",
    ),
    Field("traceback", {"type": "string"}, "for a failed job whose error was not a user error"),
)
_BY_NAME = {f.name: f for f in FIELDS}
#: Provenance a submitted record must carry (``a.b``: key ``b`` of field ``a``).
PROVENANCE_FIELDS = (
    "environment.hnnbench",
    "environment.python",
    "environment.platform",
    "created_at",
)
#: The field holding the plugin version of a record's system and of its model.
VERSION_FIELDS: tuple[tuple[Literal["system", "model"], str], ...] = (
    ("system", "system_version"),
    ("model", "model_version"),
)


def _check_names() -> None:
    unknown = [
        n
        for n in (
            *JOB_FIELDS,
            *FRAME_COLUMNS,
            *ID_COLUMNS,
            *BOARD_KEY,
            *FAMILY_KEY,
            *(p.split(".")[0] for p in PROVENANCE_FIELDS),
            *(n for pair in VERSION_FIELDS for n in pair),
        )
        if n not in _BY_NAME and n not in LOADER_FIELDS and n not in DERIVED_COLUMNS
    ]
    if unknown or set(LOADER_FIELDS) & set(_BY_NAME):
        raise AssertionError(f"record names not declared in FIELDS: {unknown}")


_check_names()


def new_record(**values: Any) -> dict[str, Any]:
    """A job's new record: every field a job writes (:attr:`Field.written`), in
    :data:`FIELDS` order, with its :attr:`Field.initial` value unless given in
    ``values``. Raises ``TypeError`` for a value of a field the record does not start
    with, or a field without an initial value that is not given."""
    extra = sorted(set(values) - {f.name for f in FIELDS if f.written})
    if extra:
        raise TypeError(f"new_record(): {', '.join(extra)} is not a field a new record starts with")
    out: dict[str, Any] = {}
    for f in FIELDS:
        if not f.written:
            continue
        if f.name in values:
            out[f.name] = values[f.name]
        elif f.initial is not _NONE:
            out[f.name] = copy.deepcopy(f.initial)
        else:
            raise TypeError(f"new_record(): no value for {f.name}")
    return out


def json_schema() -> dict[str, Any]:
    """The record's JSON Schema (draft 2020-12), from :data:`FIELDS`."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://github.com/hnnbench/hnnbench/record.schema.json",
        "title": "hnnbench run record (result.json)",
        "description": (
            "One job: a system, a model, a seed. Written by hnnbench._record.store.write_record "
            "from the definition in hnnbench/_record/fields.py (this file is generated "
            'from it); strict JSON: a non-finite metric value is the string "inf" or '
            '"-inf", an undefined one null (docs/ARCHITECTURE.md).'
        ),
        "type": "object",
        "required": [f.name for f in FIELDS if f.presence == REQUIRED],
        "properties": {
            f.name: {**copy.deepcopy(dict(f.schema)), "description": f.description} for f in FIELDS
        },
    }


#: The shipped JSON Schema, written from :func:`json_schema` by
#: ``python scripts/maintainer/record_schema.py --write``.
SCHEMA_FILE = Path(__file__).resolve().parents[1] / "resources" / "record.schema.json"


def schema_text() -> str:
    """The text of :data:`SCHEMA_FILE`: :func:`json_schema` as indented JSON."""
    return json.dumps(json_schema(), indent=2) + "\n"


RECORD_NAME = "result.json"
#: A job's arrays (rollouts, true states, training history) beside its record.
ROLLOUT_NAME = "rollout.npz"
#: Statuses of a job that is done and is not redone on resume.
FINISHED = ("ok", "diverged", "skipped")
