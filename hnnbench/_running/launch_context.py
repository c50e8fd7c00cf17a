"""The launch context: what the ``hnnbench`` command (or a Python API call) tells the
jobs it starts (docs/ARCHITECTURE.md, "The path of one job").

- ``command``: the command line as typed, stored in every record;
- ``n_jobs``: the sweep's size, for the ``[k/N]`` progress lines;
- ``cli_pid`` and ``host``: the command's process and host. Their presence means
  "started by the ``hnnbench`` command", which makes a job pin itself to one core
  (:mod:`~hnnbench._running.affinity`); a worker on the command's host whose command has
  gone exits at its next progress update instead of training on as an orphan
  (:func:`abandoned`);
- ``pinned``: the sweeps of groups the sweeper restores (:class:`~hnnbench._sweeping.
  plan.Plan`);
- in the command's process only: the jobs' ``outcomes`` as they are collected, and the
  jobs the plan has ``prepared`` (validated), which an in-process job then does not
  validate again.

In the command's own process (a single run, the basic launcher, the tuner, ``hnnbench
check --rerun``) the context is this Python object (:func:`launched`, :func:`current`).
Launchers that run jobs in other processes (joblib's workers, submitit's Slurm tasks,
Ray) see none of the command's Python state, only its environment: for them the sweeper
also writes the part a job reads into one environment variable, :data:`ENV`
(:func:`exported`), which :func:`current` reads where no context was set in-process.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Optional

from hnnbench._contracts import jsonio

__all__ = ["ENV", "LaunchContext", "abandoned", "current", "exported", "launched", "local"]

#: The environment variable holding the context for jobs in other processes (JSON).
ENV = "HNNBENCH_LAUNCH"
#: The fields a job in another process reads (:data:`ENV`).
_EXPORTED = ("command", "n_jobs", "cli_pid", "host", "pinned")


@dataclass
class LaunchContext:
    """See the module docstring."""

    command: Optional[str] = None
    n_jobs: Optional[int] = None
    cli_pid: Optional[int] = None
    host: Optional[str] = None
    #: swept groups pinned for Hydra's sweep-wide config (``Plan.pinned``).
    pinned: Optional[dict[str, str]] = None
    #: the outcomes collected so far: ``{"record", "kept"}`` per seed, ``{"lost"}`` per
    #: job that returned none (in the command's process only).
    outcomes: list[dict[str, Any]] = field(default_factory=list, repr=False)
    #: jobs the plan validated, by their config's fingerprint
    #: (:func:`hnnbench._running.config.fingerprint`; in the command's process only).
    prepared: dict[str, Any] = field(default_factory=dict, repr=False)

    def post(self, outcome: dict[str, Any]) -> None:
        """Keep one outcome as the record file has it (strict JSON, decoded again by
        whoever reads :attr:`outcomes`)."""
        from hnnbench._record.codec import encode

        self.outcomes.append(json.loads(json.dumps(encode(outcome), allow_nan=False)))


_current: Optional[LaunchContext] = None


def current() -> Optional[LaunchContext]:
    """The context of the ``hnnbench`` command this process works for, or ``None``: the
    one set in this process (:func:`launched`), else the one in :data:`ENV`."""
    if _current is not None:
        return _current
    value = os.environ.get(ENV)
    if not value:
        return None
    try:
        data = jsonio.loads(value)
        return LaunchContext(**{k: data.get(k) for k in _EXPORTED})
    except (ValueError, TypeError, AttributeError):  # set by hand: "started by the CLI"
        return LaunchContext()


def local() -> Optional[LaunchContext]:
    """The context set in this process (:func:`launched`), the one that collects the
    outcomes; ``None`` in a launcher's worker or outside a command."""
    return _current


def abandoned() -> bool:
    """Whether this process works for an ``hnnbench`` command on this host that no longer
    exists (``False`` in the command's own process, elsewhere, or when unknown)."""
    import socket

    ctx = current()
    if ctx is None or not isinstance(ctx.cli_pid, int) or ctx.cli_pid == os.getpid():
        return False
    if ctx.host is None or ctx.host != socket.gethostname():
        return False
    try:
        os.kill(ctx.cli_pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # exists, owned by someone else, or cannot tell
        return False
    return False


@contextlib.contextmanager
def launched(context: LaunchContext) -> Iterator[LaunchContext]:
    """Set ``context`` for this process while the block runs; restore the one before,
    so a notebook's later in-process runs are not affected."""
    global _current
    previous, _current = _current, context
    try:
        yield context
    finally:
        _current = previous


@contextlib.contextmanager
def exported(context: Optional[LaunchContext]) -> Iterator[None]:
    """Put ``context`` (its fields a job reads) into :data:`ENV` while the block runs,
    for the processes a launcher starts then; restore what was there before."""
    if context is None:
        yield
        return
    previous = os.environ.get(ENV)
    os.environ[ENV] = json.dumps({k: getattr(context, k) for k in _EXPORTED})
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = previous
