"""The record's names that plugins and the registry rely on: plugin and profile names,
statuses, tracks, the reference roles, and the leaderboard columns no metric may be
named after (docs/ARCHITECTURE.md, "The result record").
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import Any, Optional

__all__ = [
    "BOARD_KEY",
    "DEFAULT_TRACK",
    "DERIVED_COLUMNS",
    "FAMILY_KEY",
    "FRAME_COLUMNS",
    "ID_COLUMNS",
    "JOB_FIELDS",
    "LOADER_FIELDS",
    "NAME_PATTERN",
    "ORACLE",
    "PROVENANCE_COLUMNS",
    "REFERENCES",
    "RESERVED",
    "STANDING_STILL",
    "STATUSES",
    "STATUS_COLUMNS",
    "TIMINGS",
    "TRACKS",
    "metric_name_problem",
    "name_problem",
    "pattern_matches",
]


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
#: The one pattern of a system, model, metric, claim-set or profile name: a plain file-name
#: component (no separator, no dot, nothing a Markdown table or a shell reads specially),
#: so a name can be a directory, a file-name part and a table cell as it is. The record
#: schema's ``system``, ``model`` and ``profile`` fields, the registry (a plugin of
#: another name is refused) and :func:`hnnbench._contracts.paths.safe_join` hold names to it.
NAME_PATTERN = "^[a-z][a-z0-9_]{0,63}$"
#: Fields the loader adds to each record it returns (never written): the record's
#: directory, and the directory it was found under.
LOADER_FIELDS = ("path", "source")
#: The fields that say which job a record is of (with the variant, from its overrides:
#: ``hnnbench._results.leaderboard.variant_labels``); no override of them defines a variant.
JOB_FIELDS = ("system", "model", "seed", "profile")
#: Timings averaged into the leaderboard (``<name>_mean``); tables show ``cpu_s`` (the
#: CPU time of the job's process, which a crowded machine does not inflate) where wall
#: time (``total_s``) is not the point.
TIMINGS = ("fit_s", "eval_s", "total_s", "cpu_s")
#: Identity and status columns of a leaderboard, in order (``reason``: why runs of the
#: pair were not ``ok``, from their records' ``error``).
ID_COLUMNS = ("profile", "system", "model", "backend", "family", "ranked", "reference")
STATUS_COLUMNS = (
    "n_seeds",
    "seeds",
    *(f"n_{s}" for s in STATUSES),
    "n_untrained",
    "n_unconverged",
    "status",
    "reason",
)
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
    "tuning_cpu_s": "tuning.cpu_s: the CPU seconds of the tuning that chose a tuned run's settings",
    "tuning_study": "tuning.study: the study that chose a tuned run's settings (one per fold "
    "on a measured system)",
    "git_commit": "environment.git_commit",
    "machine": "environment.host, else environment.platform",
    "trained": "selection.trained (false: the run did not train; None: no selection)",
    "reference": "the record's reference role (zero_field, true_field; records before "
    "schema 3: the installed model's), empty for a competitor",
    "converged": "selection.converged (whether the criterion stopped improving over the "
    "last 20% of steps; None: not measured)",
    "criterion_value": "selection.validation_loss: the selection criterion at the scored "
    "checkpoint (None: no selection)",
    "tuning_trial_seed": "whether a tuned run's seed is among tuning.trial_seeds (a seed "
    "its study's trials trained); None for a run of another track or a tuned record that "
    "names no trial seeds",
}
#: The columns of a records frame that are not metrics or timings, in order: record
#: fields, loader fields and :data:`DERIVED_COLUMNS`.
FRAME_COLUMNS = (
    "system",
    "model",
    "variant",
    "track",
    "backend",
    "family",
    "ranked",
    "reference",
    "seed",
    "profile",
    "status",
    "error",
    "steps",
    "device",
    *LOADER_FIELDS,
    "git_commit",
    "machine",
    "trained",
    "converged",
    "created_at",
    "tuning_cpu_s",
    "tuning_study",
    "criterion_value",
    "tuning_trial_seed",
)
#: Columns of a records frame that are not metrics.
RESERVED = frozenset(FRAME_COLUMNS)


def shown_value(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a message is one short line)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def one_line(text: str, limit: int = 400) -> str:
    """``text`` with every character that is not printable escaped (``\\n``,
    ``\\x1b``...), cut to ``limit`` characters: a message of one line, whatever a
    record's keys or values hold."""
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return shown if len(shown) <= limit else shown[: limit - 3] + "..."


_PLAIN_KEY = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,63}\Z")


def shown_key(key: Any) -> str:
    """A mapping key as part of a field path in a message: the key itself when it is
    plain text (letters, digits, ``_.+-``; at most 64 characters), else
    :func:`shown_value` (quoted, escaped), so a key never breaks the message's line."""
    return key if isinstance(key, str) and _PLAIN_KEY.match(key) else shown_value(key, 40)


@lru_cache(maxsize=64)
def _compiled(pattern: str) -> re.Pattern[str]:
    # JSON Schema's "$" is the end of the text; Python's also matches before a final
    # newline, which would let "spring\n" through.
    return re.compile(pattern[:-1] + r"\Z" if pattern.endswith("$") else pattern)


def pattern_matches(pattern: str, text: str) -> bool:
    """Whether ``text`` matches the JSON Schema ``pattern`` (``$``: the end of the text,
    as in JSON Schema, never before a final newline)."""
    return _compiled(pattern).search(text) is not None


def name_problem(kind: str, name: Any) -> Optional[str]:
    """Why ``name`` cannot name a ``kind`` (system, model, metric, claims, profile), or
    ``None``: it must match :data:`NAME_PATTERN`."""
    if isinstance(name, str) and pattern_matches(NAME_PATTERN, name):
        return None
    return (
        f"{shown_value(name)} is not a {kind} name: use 1 to 64 lower-case letters, digits "
        "and '_', starting with a letter"
    )


def metric_name_problem(name: str) -> Optional[str]:
    """Why ``name`` cannot name a metric, or ``None``. Metrics share a records frame
    with identity fields and timings, and a leaderboard with status columns and the
    ``_mean``/``_std`` columns built from them, so a metric may not take those names."""
    taken = RESERVED | set(STATUS_COLUMNS) | set(PROVENANCE_COLUMNS) | set(TIMINGS)
    if name_problem("metric", name):
        return (
            f"{shown_value(name)} is not a metric name: use 1 to 64 lower-case letters, "
            "digits and '_', starting with a letter"
        )
    if name in taken:
        return f"the metric name '{name}' is a leaderboard column; choose another name"
    for suffix in ("_s", "_sem", "_mean", "_std"):
        if name.endswith(suffix):
            return (
                f"the metric name '{name}' ends in '{suffix}', which tables reserve "
                "for timings and aggregates; choose another name"
            )
    return None
