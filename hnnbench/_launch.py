"""The launch context: what the ``hnnbench`` command tells the jobs it starts.

A sweep's jobs may run in launcher workers (joblib's processes, Slurm tasks), which
see the command's environment but none of its Python state. These facts travel
there, in one environment variable (:data:`ENV`, JSON):

- ``command``: the command line as typed, stored in every record;
- ``n_jobs``: the sweep's size, for the ``[k/N]`` progress lines;
- ``cli_pid``: the command's process id. Its presence means "started by the
  ``hnnbench`` command", which makes a job pin itself to one core
  (:mod:`hnnbench._affinity`); a notebook or test calling
  :func:`hnnbench._job.run_job` directly is left alone;
- ``host``: the command's host name. A worker on the same host whose command has gone
  (killed without its process group, e.g. ``kill PID``) exits at its next progress
  update, writing no record, instead of training on as an orphan (:func:`abandoned`,
  :mod:`hnnbench._progress`); a worker on another host (Slurm) never checks;
- ``returns`` and ``pinned``: the command's channel file for the jobs' outcomes, and the
  sweeps of groups its sweeper restores (:mod:`hnnbench._sweep`).

:func:`launched` sets it for the duration of a command and restores what was there
before, so a notebook's later in-process runs are not affected.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from typing import Optional

__all__ = ["ENV", "LaunchContext", "abandoned", "current", "launched"]

#: The environment variable holding the context (JSON).
ENV = "HNNBENCH_LAUNCH"


@dataclass(frozen=True)
class LaunchContext:
    """See the module docstring."""

    command: Optional[str] = None
    n_jobs: Optional[int] = None
    cli_pid: Optional[int] = None
    host: Optional[str] = None
    #: the command's channel file: jobs' outcomes (``hnnbench._sweep``).
    returns: Optional[str] = None
    #: swept groups pinned for Hydra's sweep-wide config (``hnnbench._sweep.Plan``).
    pinned: Optional[dict[str, str]] = None


def current() -> Optional[LaunchContext]:
    """The context of the ``hnnbench`` command this process works for, or ``None``."""
    value = os.environ.get(ENV)
    if not value:
        return None
    try:
        data = json.loads(value)
        return LaunchContext(**{k: data.get(k)
                                for k in ("command", "n_jobs", "cli_pid", "host", "returns",
                                          "pinned")})
    except (ValueError, TypeError, AttributeError):  # set by hand: "started by the CLI"
        return LaunchContext()


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
def launched(context: LaunchContext) -> Iterator[None]:
    """Set ``context`` for this process and the workers it starts; restore on exit."""
    previous = os.environ.get(ENV)
    os.environ[ENV] = json.dumps(asdict(context))
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = previous
