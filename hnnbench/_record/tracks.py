"""A record's track and tuning: its track, the settings a tuned record's tuning
selected, and whether track and tuning hold together (docs/TUNING.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Optional

from hnnbench._contracts.names import DEFAULT_TRACK, shown_value

__all__ = [
    "SELECTED_ON",
    "STEPS_SETTING",
    "TRACK_KEYS",
    "on_trial_seed",
    "study_summary_name",
    "track_of",
    "track_problem",
    "tuned_settings",
]


#: What a tuned record's ``tuning`` says selection was made on (never test).
SELECTED_ON = "validation"
#: Config keys that say a run's track (never a variant of its row).
TRACK_KEYS = ("track", "tuning")


def study_summary_name(model: str, fold: int | None) -> str:
    """A tuned study's summary file name (``<out>/tuning/<system>/<name>``):
    ``<model>[.fold<k>].json``, ``k`` the fold of a measured system's study."""
    return f"{model}{'' if fold is None else f'.fold{fold}'}.json"


def track_of(record: Mapping[str, Any]) -> str:
    """The track of a record (:data:`TRACKS`): its ``track``, :data:`DEFAULT_TRACK`
    where it has none (or a value that is not a string, which the schema refuses)."""
    value = record.get("track")
    return value if isinstance(value, str) and value else DEFAULT_TRACK


def on_trial_seed(record: Mapping[str, Any]) -> Optional[bool]:
    """Whether a tuned record's seed is one of its study's trial seeds
    (``tuning.trial_seeds``): then the run is the selected trial again, chosen for its
    score on that very seed, and no row reads it (docs/TUNING.md, "Which seeds a tuned
    row reads"). ``None`` for a record with no ``tuning`` block or no list of trial seeds."""
    tuning = record.get("tuning")
    seeds = tuning.get("trial_seeds") if isinstance(tuning, Mapping) else None
    if not isinstance(seeds, (list, tuple)):
        return None
    return record.get("seed") in seeds


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
        return (
            f"tuning.selected_on: {shown_value(tuning.get('selected_on'))}, but the tuned "
            f"track selects on {SELECTED_ON} only"
        )
    selected = tuning.get("selected")
    for key in ("trials", "steps"):
        value = tuning.get(key)
        if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
            return (
                f"tuning.{key}: {shown_value(value)}; a tuned result states its budget "
                "(a tuner's trial record is not a result)"
            )
    if not isinstance(selected, Mapping) or not selected:
        return "tuning.selected: missing; a tuned result states the settings it selected"
    for key, value in {**selected, STEPS_SETTING: tuning["steps"]}.items():
        node: Any = config
        for part in str(key).split("."):
            node = node.get(part) if isinstance(node, Mapping) else None
        if node != value or type(node) is bool and type(value) is not bool:
            return (
                f"tuning.selected: {key}={shown_value(value)}, but the record's config has "
                f"{shown_value(node)}"
            )
    return None
