"""User-facing errors.

Every error a user can cause (a bad override, missing data, an unknown plugin name, a
missing backend) is an :class:`HnnbenchError`. The CLI prints its message as one line
and exits non-zero, with no traceback. Messages say what was wrong, what was expected
and how to fix it.
"""

from __future__ import annotations

import argparse
import difflib
from collections.abc import Iterable
from typing import Any, ClassVar


class HnnbenchError(Exception):
    """A problem the user can fix. ``str(err)`` is a single, complete line (whatever
    the message was built from: line breaks and runs of whitespace become one space)."""

    def __str__(self) -> str:
        return " ".join(super().__str__().split())


class ConfigError(HnnbenchError):
    """An invalid configuration value or override."""


class UnknownNameError(ConfigError):
    """An unknown system, model or profile name."""

    def __init__(self, kind: str, name: str, available: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.available = sorted(available)
        super().__init__(unknown_name_message(kind, name, self.available))


class DataError(HnnbenchError):
    """Missing or corrupt data files."""


class UnsafePathError(HnnbenchError, ValueError):
    """A path built from a name (a record's or a plugin's) that is not one plain file-name
    component, or that would lead outside its root (:func:`hnnbench._contracts.paths.safe_join`)."""


class BackendMissingError(HnnbenchError):
    """An optional backend (torch, JAX) is not installed."""


class ModelOutputError(HnnbenchError):
    """A model method returned an array of another shape or dtype than its contract
    documents (docs/PLUGINS.md): the job is recorded ``failed`` with this one line, which
    names the method, the expected and the actual shape (:mod:`hnnbench._contracts.outputs`)."""


class UnsupportedPair(Exception):
    """This model cannot run on this system (raised by a model's ``fit`` when that only
    shows in the data, e.g. no trajectory windows). Not a user error: the job is
    recorded as ``skipped`` with the message as its reason."""


class RolloutDiverged(Exception):
    """A rollout produced non-finite states or the ODE solver gave up.

    Not a user error: the job is recorded with status ``diverged`` and the sweep goes on.
    """


class JobTimeout(BaseException):
    """A job ran past its wall-clock limit (``timeout_s``). Raised inside the job by
    its timer; the job is recorded as ``timeout`` and the sweep goes on. A
    :class:`BaseException`, like :class:`KeyboardInterrupt`, so that a plugin's
    ``except Exception`` does not swallow it."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        super().__init__(f"the job ran past its time limit of {seconds:g} s (timeout_s)")


class OneLineArgumentParser(argparse.ArgumentParser):
    """argparse that raises a one-line :attr:`error_type` (naming the problem and the
    usage) instead of printing usage and exiting; a subcommand sets its own error type."""

    error_type: ClassVar[type[HnnbenchError]] = HnnbenchError

    def error(self, message: str) -> Any:
        usage = " ".join(self.format_usage().split()[1:])
        raise self.error_type(f"{message} (usage: {usage})")


def unknown_name_message(kind: str, name: str, available: Iterable[str]) -> str:
    """``Unknown model 'x'. Did you mean 'y'? Available: a, b, c``."""
    available = sorted(available)
    close = difflib.get_close_matches(str(name), available, n=1, cutoff=0.5)
    hint = f" Did you mean '{close[0]}'?" if close else ""
    listing = ", ".join(available) if available else "(none registered)"
    return f"Unknown {kind} '{name}'.{hint} Available: {listing}"


def require_backend(module: str, extra: str) -> None:
    """Raise a one-line :class:`BackendMissingError` if ``module`` cannot be imported."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise BackendMissingError(
            f"This model needs {module}, which is not installed. "
            f"Install it with: pip install 'hnnbench[{extra}]'"
        )
