"""Search spaces: the settings a model may be tuned over, declared next to its config
(``search_space = {setting: distribution}``), the distributions (:class:`LogUniform`,
:class:`Uniform`, :class:`IntRange`, :class:`Categorical`), and the check the registry
applies to a declared space (:func:`space_problem`; docs/TUNING.md, "Search spaces").
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Optional, Union

__all__ = [
    "Categorical",
    "Distribution",
    "FORBIDDEN_SETTINGS",
    "IntRange",
    "LogUniform",
    "SearchSpace",
    "Uniform",
    "describe",
    "distribution_json",
    "space_json",
    "space_problem",
]

#: Settings no space may hold: the step budget is the track's (every trial and every
#: model of a system trains for the same number of steps), and ``name`` is the model's.
FORBIDDEN_SETTINGS = ("name", "steps")


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class LogUniform:
    """A float drawn uniformly in ``log`` between ``low`` and ``high`` (``0 < low <
    high``)."""

    low: float
    high: float
    changes_training_loss: bool = False
    kind: ClassVar[str] = "log_uniform"

    def problem(self) -> Optional[str]:
        if not (_number(self.low) and _number(self.high) and 0 < self.low < self.high):
            return f"LogUniform({self.low!r}, {self.high!r}) needs 0 < low < high"
        return None

    def candidates(self) -> tuple[Any, ...]:
        return (float(self.low), float(self.high))

    def text(self) -> str:
        return f"log-uniform [{self.low:g}, {self.high:g}]"


@dataclass(frozen=True)
class Uniform:
    """A float drawn uniformly between ``low`` and ``high`` (``low < high``)."""

    low: float
    high: float
    changes_training_loss: bool = False
    kind: ClassVar[str] = "uniform"

    def problem(self) -> Optional[str]:
        if not (_number(self.low) and _number(self.high) and self.low < self.high):
            return f"Uniform({self.low!r}, {self.high!r}) needs finite low < high"
        return None

    def candidates(self) -> tuple[Any, ...]:
        return (float(self.low), float(self.high))

    def text(self) -> str:
        return f"uniform [{self.low:g}, {self.high:g}]"


@dataclass(frozen=True)
class IntRange:
    """An integer of ``[low, high]`` (both included); ``log``: uniform in ``log``
    (``low >= 1``)."""

    low: int
    high: int
    log: bool = False
    changes_training_loss: bool = False
    kind: ClassVar[str] = "int"

    def problem(self) -> Optional[str]:
        ints = all(isinstance(v, int) and not isinstance(v, bool) for v in (self.low, self.high))
        if not ints or not self.low < self.high:
            return f"IntRange({self.low!r}, {self.high!r}) needs integers low < high"
        if self.log and self.low < 1:
            return f"IntRange({self.low!r}, {self.high!r}, log=True) needs low >= 1"
        return None

    def candidates(self) -> tuple[Any, ...]:
        return (self.low, self.high)

    def text(self) -> str:
        return f"int [{self.low}, {self.high}]" + (" (log)" if self.log else "")


@dataclass(frozen=True)
class Categorical:
    """One of ``choices``: distinct JSON scalars (strings, numbers, booleans)."""

    choices: tuple[Any, ...]
    changes_training_loss: bool = False
    kind: ClassVar[str] = "categorical"

    def problem(self) -> Optional[str]:
        choices = self.choices
        if not isinstance(choices, tuple) or not choices:
            return f"Categorical({choices!r}) needs a non-empty tuple of choices"
        for value in choices:
            if not (isinstance(value, (str, bool)) or _number(value)):
                return f"Categorical choice {value!r} is not a string, a finite number or a boolean"
        if len({(type(v), v) for v in choices}) != len(choices):
            return f"Categorical({choices!r}) repeats a choice"
        return None

    def candidates(self) -> tuple[Any, ...]:
        return tuple(self.choices)

    def text(self) -> str:
        return "{" + ", ".join(str(v) for v in self.choices) + "}"


Distribution = Union[LogUniform, Uniform, IntRange, Categorical]
#: ``{setting: distribution}``; ``setting`` is a field of the model's config.
SearchSpace = Mapping[str, Distribution]
_KINDS = (LogUniform, Uniform, IntRange, Categorical)


def describe(space: SearchSpace) -> str:
    """One line: ``lr: log-uniform [0.0001, 0.01]; hidden: {64, 128}; ...``."""
    return "; ".join(f"{name}: {dist.text()}" for name, dist in space.items())


def distribution_json(dist: Distribution) -> dict[str, Any]:
    """A distribution as JSON: ``{"kind": "log_uniform", "low": ..., "high": ...}``."""
    out: dict[str, Any] = {"kind": dist.kind}
    for f in dataclasses.fields(dist):
        value = getattr(dist, f.name)
        if f.name == "changes_training_loss" and not value:
            continue
        if f.name == "log" and not value:
            continue
        out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


def space_json(space: SearchSpace) -> dict[str, dict[str, Any]]:
    """The whole space as JSON (records, ``hnnbench list --json``)."""
    return {name: distribution_json(dist) for name, dist in space.items()}


def space_problem(space: Any, config_cls: type) -> Optional[str]:
    """Why ``space`` is not a valid search space of a model whose config is
    ``config_cls``, or ``None``: a mapping of config fields (not
    :data:`FORBIDDEN_SETTINGS`) to distributions, each valid, whose bounds and choices
    the config accepts (its ``validate()``)."""
    if not isinstance(space, Mapping):
        return (
            f"search_space must be a mapping of setting -> distribution, not {type(space).__name__}"
        )
    if not space:
        return "search_space is empty: declare at least one setting, or None"
    fields = (
        {f.name for f in dataclasses.fields(config_cls)}
        if dataclasses.is_dataclass(config_cls)
        else set()
    )
    for name, dist in space.items():
        if not isinstance(name, str) or name not in fields:
            return (
                f"search_space names {name!r}, which is not a setting of "
                f"{config_cls.__name__} (settings: {', '.join(sorted(fields))})"
            )
        if name in FORBIDDEN_SETTINGS:
            return (
                f"search_space names {name!r}: the step budget and the name are the "
                "tuning track's, the same for every model; remove it"
            )
        if not isinstance(dist, _KINDS):
            return (
                f"search_space[{name!r}] is {dist!r}: expected LogUniform, Uniform, "
                "IntRange or Categorical"
            )
        problem = dist.problem()
        if problem is not None:
            return f"search_space[{name!r}]: {problem}"
        for value in dist.candidates():
            try:
                config_cls(**{name: value}).validate()
            except Exception as err:  # noqa: BLE001 - any refusal of the config
                message = " ".join(str(err).split()) or type(err).__name__
                return (
                    f"search_space[{name!r}]: the value {value!r} is refused by "
                    f"{config_cls.__name__}: {message}"
                )
    return None
