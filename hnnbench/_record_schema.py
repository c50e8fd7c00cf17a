"""The run record (``result.json``), defined once: its fields, and the names built from
them.

:data:`FIELDS` declares every field a record may hold: its JSON Schema, whether every
record has it, the value a job's record starts with, and what it means. Everything
else about the record takes its names from here:

- the JSON Schema (:func:`json_schema`; the shipped ``hnnbench/resources/
  record.schema.json`` is written from it by ``python scripts/maintainer/record_schema.py --write``,
  and tests/test_records_schema.py fails when the two disagree);
- a new record (:func:`new_record`, which ``hnnbench._job`` builds every record from);
- the quick check a loaded record must pass (:func:`shape_problems`; the full schema
  check is ``hnnbench._records.validate``);
- the columns of a records frame and a leaderboard (:data:`FRAME_COLUMNS`,
  :data:`ID_COLUMNS`, ...), and the fields the gate reads (:data:`PROVENANCE_FIELDS`,
  :data:`VERSION_FIELDS`);
- the rule a metric name must follow so that it never takes one of those names
  (:func:`metric_name_problem`);
- what a record from someone else's machine is held to (docs/LEADERBOARD.md, "Threat
  model"): the one pattern of plugin and profile names (:data:`NAME_PATTERN`, checked by
  the schema, the registry and every path built from a name), the pattern of a
  variant's ``key=value`` tokens (:data:`VARIANT_TOKEN_PATTERN`), a record's largest size
  and nesting (:data:`MAX_RECORD_BYTES`, :data:`MAX_DEPTH`) and its ``created_at``
  (:func:`created_at_problem`).

A contract (it imports nothing else of hnnbench): the registry checks metric names
against it, the job, the loader, the leaderboard and the gate take their names from it.
"""

from __future__ import annotations

import copy
import datetime as _dt
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal, Optional

__all__ = [
    "BOARD_KEY",
    "FAMILY_KEY",
    "DEFAULT_TRACK",
    "MAX_DEPTH",
    "MAX_RECORD_BYTES",
    "NAME_PATTERN",
    "VARIANT_TOKEN_PATTERN",
    "DERIVED_COLUMNS",
    "FIELDS",
    "FRAME_COLUMNS",
    "ID_COLUMNS",
    "JOB_FIELDS",
    "LOADER_FIELDS",
    "PROVENANCE_COLUMNS",
    "PROVENANCE_FIELDS",
    "RESERVED",
    "ORACLE",
    "REFERENCES",
    "SCHEMA_VERSION",
    "SCHEMA_VERSIONS",
    "STANDING_STILL",
    "STATUSES",
    "SELECTED_ON",
    "STATUS_COLUMNS",
    "STEPS_SETTING",
    "TIMINGS",
    "TRACKS",
    "TRACK_KEYS",
    "VERSION_FIELDS",
    "Field",
    "created_at_problem",
    "history_problems",
    "is_date_time",
    "json_schema",
    "metric_name_problem",
    "name_problem",
    "new_record",
    "pattern_matches",
    "shape_problems",
    "track_of",
    "track_problem",
    "tuned_settings",
    "variant_problem",
]

#: The version of the records this hnnbench writes, and the versions it reads.
SCHEMA_VERSION = 3
SCHEMA_VERSIONS = (1, 2, 3)
#: A job's outcome.
STATUSES = ("ok", "diverged", "failed", "skipped", "timeout")
#: The benchmark's tracks (docs/TUNING.md): each system's shared protocol, an
#: equal-budget tuning selected on validation, and a family paper's own recipe. A record
#: without ``track`` (every record before 0.3's tracks) is of the protocol track.
TRACKS = ("protocol", "tuned", "recipe")
DEFAULT_TRACK = "protocol"
#: The roles of a trivial reference model (``Model.reference``, the record's
#: ``reference``): standing still, the zero field (``x̂(t) = x₀``), which every ranked
#: leader must beat, and the oracle, the true field.
REFERENCES = ("zero_field", "true_field")
STANDING_STILL, ORACLE = REFERENCES
#: What a tuned record's ``tuning`` says selection was made on (never test).
SELECTED_ON = "validation"

#: The one pattern of a system, model, metric, claim-set or profile name: a plain file-name
#: component (no separator, no dot, nothing a Markdown table or a shell reads specially),
#: so a name can be a directory, a file-name part and a table cell as it is. The record
#: schema's ``system``, ``model`` and ``profile`` fields, the registry (a plugin of
#: another name is refused) and :func:`hnnbench._paths.safe_join` hold names to it.
NAME_PATTERN = "^[a-z][a-z0-9_]{0,63}$"
#: One token of a variant label (``model.hidden=200``): a dotted setting, ``=``, and a
#: value of safe characters (numbers, words, JSON lists and mappings without spaces);
#: no path separator, no Markdown or HTML markup, no line break.
VARIANT_TOKEN_PATTERN = '^[A-Za-z_][A-Za-z0-9_.]{0,127}=[A-Za-z0-9_.,:+\\-\\[\\]{}"]{0,128}$'
#: The largest ``result.json`` read (bytes): a record is a few to a few hundred KB (its
#: training history is the bulk); a larger file is refused before it is parsed.
MAX_RECORD_BYTES = 2 * 1024 * 1024
#: The deepest nesting of objects and arrays in a record (a record nests 4 to 6 levels;
#: its stored config a few more); deeper JSON is refused before the schema sees it.
MAX_DEPTH = 32
#: How far in the future (the reader's clock) a ``created_at`` may be: clocks differ.
FUTURE_SKEW = _dt.timedelta(hours=1)

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
_INT_OR_NULL: Mapping[str, Any] = {"type": ["integer", "null"], "minimum": 0}
#: Where a plugin came from (``plugins.system``, ``plugins.model``).
_PLUGIN: Mapping[str, Any] = {
    "type": "object", "required": ["name", "version", "distribution", "distribution_version"],
    "properties": {"name": {"type": "string"}, "version": _STRING_OR_NULL,
                   "distribution": _STRING_OR_NULL, "distribution_version": _STRING_OR_NULL}}


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
    Field("schema_version", {"enum": list(SCHEMA_VERSIONS)},
          "the version of this format", REQUIRED, SCHEMA_VERSION),
    Field("system", {"type": "string", "pattern": NAME_PATTERN},
          "the system's registered name", REQUIRED),
    Field("system_version", _STRING_OR_NULL, "the system plugin's version", REQUIRED, None),
    Field("model", {"type": "string", "pattern": NAME_PATTERN},
          "the model's registered name", REQUIRED),
    Field("model_version", _STRING_OR_NULL, "the model plugin's version", REQUIRED, None),
    Field("backend", _STRING_OR_NULL, "the model's backend (torch, jax, numpy)", REQUIRED,
          None),
    Field("family", _STRING_OR_NULL, "the model family (e.g. hnn), grouping backends"),
    Field("ranked", {"type": "boolean"},
          "false for references such as the oracle: shown, never ranked"),
    Field("reference", {"enum": [None, *REFERENCES]},
          "the role of a trivial reference (zero_field: standing still, which a leader "
          "must beat; true_field: the oracle), null for a competitor; absent in records "
          "before schema 3"),
    Field("plugins", {"type": "object", "required": ["system", "model"],
                      "properties": {"system": _PLUGIN, "model": _PLUGIN}},
          "the packages that provided the system and the model: each plugin's name, its "
          "version, its distribution and the distribution's version (absent in records "
          "before 0.3)"),
    Field("seed", {"type": "integer", "minimum": 0},
          "the seed of data, evaluation and initial weights", REQUIRED),
    Field("profile", {"type": "string", "pattern": NAME_PATTERN},
          "the profile (quick, paper)", REQUIRED),
    Field("status", {"enum": list(STATUSES)}, "the job's outcome", REQUIRED, "failed"),
    Field("error", _STRING_OR_NULL, "why the job is not ok", REQUIRED, None),
    Field("metrics", {"type": "object", "propertyNames": {"pattern": NAME_PATTERN},
                      "additionalProperties": {
              "type": "object", "required": ["mean", "sem"],
              "properties": {"mean": VALUE, "sem": VALUE}}},
          "{name: {mean, sem}} for every registered metric", REQUIRED, {}),
    Field("timings", {"type": "object", "additionalProperties": {"type": "number",
                                                                 "minimum": 0}},
          "wall and CPU seconds of the job's parts", REQUIRED, {}),
    Field("steps", {"type": "integer", "minimum": 0}, "optimizer steps taken", REQUIRED, 0),
    Field("device", _STRING_OR_NULL, "the device used", WRITTEN, None),
    Field("cpu_pin", {"type": ["integer", "null"]},
          "the CPU the job's process was pinned to"),
    Field("train", {"type": ["object", "null"]},
          "the training protocol (null for a model without a training loop)"),
    Field("data", {"type": "object"},
          "cache hit, SHA-256 of the dataset and evaluation files, sizes, generator "
          "metadata", WRITTEN, {}),
    Field("history", {"type": "object", "additionalProperties": {
              "type": "array", "items": VALUE}},
          "the training log: step, train_loss, val_loss (test_loss in records before "
          "the validation split)"),
    Field("selection", {
              "type": "object",
              "required": ["step", "validation_loss", "evaluations", "first_step",
                           "trained"],
              "properties": {"rule": {"type": "string"},
                             "criterion": _STRING_OR_NULL,
                             "step": {"type": "integer", "minimum": 0},
                             "validation_loss": VALUE,
                             "evaluations": {"type": "integer", "minimum": 0},
                             "first_step": {"type": "integer", "minimum": 0},
                             "trained": {"type": "boolean"},
                             "stopped": _STRING_OR_NULL,
                             "points": {"type": "integer", "minimum": 0},
                             "best_step": _INT_OR_NULL, "best_value": VALUE,
                             "final_step": _INT_OR_NULL, "final_value": VALUE,
                             "final_se": VALUE,
                             "late_step": _INT_OR_NULL, "late_value": VALUE,
                             "late_se": VALUE,
                             "converged": {"type": ["boolean", "null"]}}},
          "the scored checkpoint of a model that selects on validation: the criterion "
          "(schema 3; docs/METRICS.md, 'Checkpoint selection'), the scored step and its "
          "criterion value (validation_loss), the evaluations made, the first one's step, "
          "whether it trained past that (false: 'did not train'), why training stopped "
          "early; and the lowest, final and late (80%) checkpoints' values with the paired "
          "standard errors of final - lowest and late - final, and whether the criterion "
          "stopped improving over the last 20% of steps (converged)"),
    Field("config", {"type": "object"}, "the fully resolved job config", REQUIRED),
    Field("overrides", {"type": ["array", "null"], "items": {"type": "string"}},
          "Hydra's overrides", WRITTEN),
    Field("command", _STRING_OR_NULL, "the command line as typed", WRITTEN),
    Field("rerun_command", _STRING_OR_NULL, "a single-run command that reproduces the job",
          WRITTEN),
    Field("environment", {
              "type": "object",
              "required": ["hnnbench", "python", "platform", "git_commit"],
              "properties": {"hnnbench": _STRING_OR_NULL, "git_commit": _STRING_OR_NULL}},
          "versions, platform, machine, host, git commit", REQUIRED),
    Field("created_at", {"type": "string", "format": "date-time"}, "UTC timestamp",
          REQUIRED),
    Field("weights_file", _STRING_OR_NULL,
          "the weights file the model wrote next to the record"),
    Field("metric_errors", {"type": "object", "additionalProperties": {"type": "string"}},
          "metrics whose computation raised, and the message"),
    Field("seed_batch", {"type": "array", "items": {"type": "integer"}},
          "the seeds trained together with this one"),
    Field("track", {"enum": list(TRACKS)},
          "the benchmark track: protocol (each system's shared protocol), tuned (settings "
          "an equal-budget tuning selected on validation), recipe (a family paper's own "
          "recipe); absent in older records, which are protocol", WRITTEN, DEFAULT_TRACK),
    Field("tuning", {
              "type": "object",
              "required": ["selected_on"],
              "properties": {
                  "selected_on": {"enum": [SELECTED_ON]},
                  "objective": {"type": "string"},
                  "criterion": {"type": "string"},
                  "seeds_per_trial": {"type": "integer", "minimum": 1},
                  "trial_seeds": {"type": "array", "items": {"type": "integer",
                                                             "minimum": 0}},
                  "protocol_trial": {"type": ["integer", "null"], "minimum": 0},
                  "trials": {"type": "integer", "minimum": 1},
                  "steps": {"type": "integer", "minimum": 1},
                  "space": {"type": "object"},
                  "selected": {"type": "object"},
                  "selected_trial": {"type": ["integer", "null"], "minimum": 0},
                  "selected_value": VALUE,
                  "cpu_s": {"type": "number", "minimum": 0},
                  "trial": {"type": "integer", "minimum": 0},
                  "study": {"type": "string"}}},
          "how a tuned run's settings were chosen (hnnbench tune): the objective and "
          "that it was read on the validation split, the trials per model and the step "
          "budget of each, the search space, the selected settings, the CPU seconds of "
          "all trials; a trial's own record has its trial number instead of the "
          "selection"),
    Field("traceback", {"type": "string"}, "for a failed job whose error was not a user error"),
)
_BY_NAME = {f.name: f for f in FIELDS}

#: Fields the loader adds to each record it returns (never written): the record's
#: directory, and the directory it was found under.
LOADER_FIELDS = ("path", "source")

#: The fields that say which job a record is of (with the variant, from its overrides:
#: ``hnnbench._table.variant_labels``); no override of them defines a variant.
JOB_FIELDS = ("system", "model", "seed", "profile")
#: Timings averaged into the leaderboard (``<name>_mean``); tables show ``cpu_s`` (the
#: CPU time of the job's process, which a crowded machine does not inflate) where wall
#: time (``total_s``) is not the point.
TIMINGS = ("fit_s", "eval_s", "total_s", "cpu_s")
#: Identity and status columns of a leaderboard, in order (``reason``: why runs of the
#: pair were not ``ok``, from their records' ``error``).
ID_COLUMNS = ("profile", "system", "model", "backend", "family", "ranked", "reference")
STATUS_COLUMNS = ("n_seeds", "seeds", *(f"n_{s}" for s in STATUSES), "n_untrained",
                  "n_unconverged", "status", "reason")
#: What a leaderboard row is of (and its ``variant``, where runs differ in settings).
BOARD_KEY = ("profile", "system", "model")
#: What a family row is of (one competitor per family: its backends are twins; and its
#: ``variant``): :data:`BOARD_KEY` with the family in place of the model, so that a field
#: added there (e.g. a track) separates family rows, rankings and aggregates too.
FAMILY_KEY = tuple("family" if k == "model" else k for k in BOARD_KEY)
#: Provenance columns of a leaderboard: distinct values over the pair's records.
PROVENANCE_COLUMNS = ("git_commits", "machines", "dates")
#: Columns of a records frame made from a record rather than copied from its field of
#: that name.
DERIVED_COLUMNS = {
    "variant": "the settings this run differs in from the others (from overrides)",
    "track": "the record's track (protocol where the record has none)",
    "tuning_cpu_s": "tuning.cpu_s: the CPU seconds of the tuning that chose a tuned "
                    "run's settings",
    "git_commit": "environment.git_commit",
    "machine": "environment.host, else environment.platform",
    "trained": "selection.trained (false: the run did not train; None: no selection)",
    "reference": "the record's reference role (zero_field, true_field; records before "
                 "schema 3: the installed model's), empty for a competitor",
    "converged": "selection.converged (whether the criterion stopped improving over the "
                 "last 20% of steps; None: not measured)",
}
#: The columns of a records frame that are not metrics or timings, in order: record
#: fields, loader fields and :data:`DERIVED_COLUMNS`.
FRAME_COLUMNS = ("system", "model", "variant", "track", "backend", "family", "ranked",
                 "reference", "seed",
                 "profile", "status", "error", "steps", "device", *LOADER_FIELDS,
                 "git_commit", "machine", "trained", "converged", "created_at",
                 "tuning_cpu_s")
#: Columns of a records frame that are not metrics.
RESERVED = frozenset(FRAME_COLUMNS)
#: Provenance a submitted record must carry (``a.b``: key ``b`` of field ``a``).
PROVENANCE_FIELDS = ("environment.hnnbench", "environment.python", "environment.platform",
                     "created_at")
#: The field holding the plugin version of a record's system and of its model.
VERSION_FIELDS: tuple[tuple[Literal["system", "model"], str], ...] = (
    ("system", "system_version"), ("model", "model_version"))


#: Config keys that say a run's track (never a variant of its row).
TRACK_KEYS = ("track", "tuning")


def track_of(record: Mapping[str, Any]) -> str:
    """The track of a record (:data:`TRACKS`): its ``track``, :data:`DEFAULT_TRACK`
    where it has none (or a value that is not a string, which the schema refuses)."""
    value = record.get("track")
    return value if isinstance(value, str) and value else DEFAULT_TRACK


#: The setting that holds a tuned run's step budget (``tuning.steps``).
STEPS_SETTING = "model.steps"


def tuned_settings(record: Mapping[str, Any]) -> frozenset[str]:
    """The settings (``model.lr``, ...) a tuned record's tuning selected, and its step
    budget (:data:`STEPS_SETTING`): its track's definition, not a variant of its row.
    Empty for any other record."""
    tuning = record.get("tuning")
    if track_of(record) != "tuned" or not isinstance(tuning, Mapping):
        return frozenset()
    selected = tuning.get("selected")
    keys = {str(k) for k in selected} if isinstance(selected, Mapping) else set()
    return frozenset(keys | {STEPS_SETTING})


def track_problem(record: Mapping[str, Any]) -> Optional[str]:
    """Why a record's track and tuning do not hold together, or ``None``: ``tuning``
    belongs to a tuned record only; a tuned record says how it was tuned (selected on
    validation, its trials, step budget and selected settings: a tuner's trial is not a
    result) and holds those settings in its config; the config's track is the
    record's."""
    track = track_of(record)
    tuning = record.get("tuning")
    config = record.get("config")
    config = config if isinstance(config, Mapping) else {}
    stored = config.get("track")
    if stored is not None and stored != track:
        return f"track: the record says {track}, its config {stored}"
    if tuning is not None and track != "tuned":
        return f"tuning: a {track} record holds a tuning; only tuned records do"
    if track != "tuned":
        return None
    if not isinstance(tuning, Mapping):
        return "tuning: a tuned record must say how it was tuned (hnnbench tune writes it)"
    if tuning.get("selected_on") != SELECTED_ON:
        return (f"tuning.selected_on: {_shown(tuning.get('selected_on'))}, but the tuned "
                f"track selects on {SELECTED_ON} only")
    selected = tuning.get("selected")
    for key in ("trials", "steps"):
        value = tuning.get(key)
        if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
            return (f"tuning.{key}: {_shown(value)}; a tuned result states its budget "
                    "(a tuner's trial record is not a result)")
    if not isinstance(selected, Mapping) or not selected:
        return "tuning.selected: missing; a tuned result states the settings it selected"
    for key, value in {**selected, STEPS_SETTING: tuning["steps"]}.items():
        node: Any = config
        for part in str(key).split("."):
            node = node.get(part) if isinstance(node, Mapping) else None
        if node != value or type(node) is bool and type(value) is not bool:
            return (f"tuning.selected: {key}={_shown(value)}, but the record's config has "
                    f"{_shown(node)}")
    return None


def _check_names() -> None:
    unknown = [n for n in (*JOB_FIELDS, *FRAME_COLUMNS, *ID_COLUMNS, *BOARD_KEY, *FAMILY_KEY,
                           *(p.split(".")[0] for p in PROVENANCE_FIELDS),
                           *(n for pair in VERSION_FIELDS for n in pair))
               if n not in _BY_NAME and n not in LOADER_FIELDS and n not in DERIVED_COLUMNS]
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
        raise TypeError(f"new_record(): {', '.join(extra)} is not a field a new record "
                        "starts with")
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
            "One job: a system, a model, a seed. Written by hnnbench._records.write_record "
            "from the definition in hnnbench/_record_schema.py (this file is generated "
            "from it); strict JSON: a non-finite metric value is the string \"inf\" or "
            "\"-inf\", an undefined one null (docs/ARCHITECTURE.md)."),
        "type": "object",
        "required": [f.name for f in FIELDS if f.presence == REQUIRED],
        "properties": {f.name: {**copy.deepcopy(dict(f.schema)), "description": f.description}
                       for f in FIELDS},
    }


#: The shipped JSON Schema, written from :func:`json_schema` by
#: ``python scripts/maintainer/record_schema.py --write``.
SCHEMA_FILE = Path(__file__).resolve().parent / "resources" / "record.schema.json"


def schema_text() -> str:
    """The text of :data:`SCHEMA_FILE`: :func:`json_schema` as indented JSON."""
    return json.dumps(json_schema(), indent=2) + "\n"


# --------------------------------------------------------------------------- quick check

_TYPES: dict[str, Any] = {
    "object": dict, "array": list, "string": str, "boolean": bool, "null": type(None),
}


def _is(value: Any, kind: str) -> bool:
    if kind == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, _TYPES[kind])


def _shown(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a message is one short line)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


@lru_cache(maxsize=64)
def _compiled(pattern: str) -> re.Pattern[str]:
    # JSON Schema's "$" is the end of the text; Python's also matches before a final
    # newline, which would let "spring\n" through.
    return re.compile(pattern[:-1] + r"\Z" if pattern.endswith("$") else pattern)


def pattern_matches(pattern: str, text: str) -> bool:
    """Whether ``text`` matches the JSON Schema ``pattern`` (``$``: the end of the text,
    as in JSON Schema, never before a final newline)."""
    return _compiled(pattern).search(text) is not None


def _value_problem(where: str, value: Any, schema: Mapping[str, Any]) -> Optional[str]:
    kinds = schema.get("type")
    if kinds is not None:
        kinds = [kinds] if isinstance(kinds, str) else list(kinds)
        if not any(_is(value, k) for k in kinds):
            return f"{where}: {_shown(value)} is not of type {', '.join(map(repr, kinds))}"
    if "enum" in schema and value not in schema["enum"]:
        return f"{where}: {_shown(value)} is not one of {list(schema['enum'])!r}"
    if isinstance(value, str) and "pattern" in schema \
            and not pattern_matches(schema["pattern"], value):
        return f"{where}: {_shown(value)} does not match {schema['pattern']!r}"
    return None


def _item_problem(where: str, value: Any, schema: Mapping[str, Any]) -> Optional[str]:
    """:func:`_value_problem`, and that of each declared property of an object."""
    problem = _value_problem(where, value, schema)
    if problem is None and isinstance(value, dict):
        for key, inner in (schema.get("properties") or {}).items():
            if key in value and (problem := _value_problem(f"{where}.{key}", value[key],
                                                           inner)):
                break
    return problem


def shape_problems(record: Mapping[str, Any]) -> list[str]:
    """What makes ``record`` (decoded JSON) unusable as a record, one line each naming
    the field (empty: usable): a missing required field, or a declared field of the
    wrong JSON type, outside its ``enum`` or not matching its ``pattern`` (a name that is
    not :data:`NAME_PATTERN`), checked two levels deep (so each metric is an object of
    values, each timing a number, each override a string). A quick check, for every
    record loaded; the full JSON Schema is checked on write and by strict loading
    (``hnnbench._records``)."""
    out = [f"'{f.name}' is a required property" for f in FIELDS
           if f.presence == REQUIRED and f.name not in record]
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
                    problem = f"{f.name}: the key {_shown(key)} does not match {names!r}"
                elif isinstance(inner, Mapping):
                    problem = _item_problem(f"{f.name}.{key}", item, inner)
                if problem is not None:
                    break
        if problem is None and f.name == "history":
            problem = next(iter(history_problems(value)), None)
        elif problem is None and isinstance(value, list):
            inner = f.schema.get("items")
            if isinstance(inner, Mapping):
                problem = next((p for i, item in enumerate(value)
                                if (p := _value_problem(f"{f.name}.{i}", item, inner))), None)
        if problem is not None:
            out.append(problem)
    return out


#: What a training history's values may be (the schema's ``history`` items; bare NaN
#: and Infinity, as schema version 1 wrote them, are floats), checked by a loop: per-item
#: JSON Schema validation of a long history took seconds.
_HISTORY_TYPES = (int, float)
_HISTORY_STRINGS = ("inf", "-inf")


def history_problems(history: Any) -> list[str]:
    """The first problem of a record's ``history`` (an object of arrays of numbers,
    ``null``, ``"inf"`` or ``"-inf"``), one line naming the field; ``[]`` if none."""
    if not isinstance(history, dict):
        return [f"history: {_shown(history)} is not of type 'object'"]
    for key, values in history.items():
        if not isinstance(values, list):
            return [f"history.{key}: {_shown(values)} is not of type 'array'"]
        for i, value in enumerate(values):
            if value is None or type(value) in _HISTORY_TYPES \
                    or (type(value) is str and value in _HISTORY_STRINGS):
                continue
            return [f"history.{key}.{i}: {_shown(value)} is not a number, null, 'inf' or "
                    "'-inf'"]
    return []


# --------------------------------------------------------------------------- names


def name_problem(kind: str, name: Any) -> Optional[str]:
    """Why ``name`` cannot name a ``kind`` (system, model, metric, claims, profile), or
    ``None``: it must match :data:`NAME_PATTERN`."""
    if isinstance(name, str) and pattern_matches(NAME_PATTERN, name):
        return None
    return (f"{_shown(name)} is not a {kind} name: use 1 to 64 lower-case letters, digits "
            "and '_', starting with a letter")


def variant_problem(label: str) -> Optional[str]:
    """Why the variant label ``label`` (space-separated ``key=value`` tokens) is not one
    of safe tokens (:data:`VARIANT_TOKEN_PATTERN`), or ``None``."""
    if not isinstance(label, str) or len(label) > 4096:
        return f"the variant {_shown(label)} is not a short text"
    for token in label.split(" ") if label else ():
        if not pattern_matches(VARIANT_TOKEN_PATTERN, token):
            return (f"the variant setting {_shown(token)} is not key=value of safe "
                    "characters (letters, digits, _ . , : + - [ ] { } \")")
    return None


# --------------------------------------------------------------------------- dates

_DATE_TIME = re.compile(r"\d{4}-\d{2}-\d{2}[Tt]\d{2}:\d{2}:\d{2}(\.\d{1,9})?"
                        r"([Zz]|[+-]\d{2}:\d{2})")


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
    record schema's ``format: date-time``, enforced (``hnnbench._records``)."""
    return isinstance(text, str) and _parse_date_time(text) is not None


def created_at_problem(value: Any, now: Optional[_dt.datetime] = None) -> Optional[str]:
    """Why ``value`` cannot be a record's ``created_at``, or ``None``: an RFC 3339
    date-time (:func:`is_date_time`) not later than ``now`` (default: this clock) plus
    :data:`FUTURE_SKEW`."""
    when = _parse_date_time(value) if isinstance(value, str) else None
    if when is None:
        return f"created_at: {_shown(value)} is not an RFC 3339 date-time"
    now = now if now is not None else _dt.datetime.now(_dt.timezone.utc)
    if when > now + FUTURE_SKEW:
        return (f"created_at: {value} is in the future (now {now.isoformat(timespec='seconds')})")
    return None


# --------------------------------------------------------------------------- metric names


def metric_name_problem(name: str) -> Optional[str]:
    """Why ``name`` cannot name a metric, or ``None``. Metrics share a records frame
    with identity fields and timings, and a leaderboard with status columns and the
    ``_mean``/``_std`` columns built from them, so a metric may not take those names."""
    taken = RESERVED | set(STATUS_COLUMNS) | set(PROVENANCE_COLUMNS) | set(TIMINGS)
    if name_problem("metric", name):
        return (f"{_shown(name)} is not a metric name: use 1 to 64 lower-case letters, "
                "digits and '_', starting with a letter")
    if name in taken:
        return f"the metric name '{name}' is a leaderboard column; choose another name"
    for suffix in ("_s", "_sem", "_mean", "_std"):
        if name.endswith(suffix):
            return (f"the metric name '{name}' ends in '{suffix}', which tables reserve "
                    "for timings and aggregates; choose another name")
    return None
