"""One CPU core per job process (:func:`claim_core`: a ``flock`` per core, every thread
pinned before any JAX computation), so that XLA runs one thread and every launcher gives
the same numbers (docs/SCALING.md, "One thread per job"). Linux only.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Optional

from hnnbench._running import launch_context
from hnnbench._running.slots import claim_least_held, slots_dir

__all__ = ["claim_core", "started_by_cli", "CLI_ENV"]

#: Set by the ``hnnbench`` command before it starts Hydra; launcher workers inherit it
#: (:mod:`hnnbench._running.launch_context`).
CLI_ENV = launch_context.ENV

_held: dict[str, object] = {}
#: Claimants per core with a lock of their own; beyond, a core chosen by process id.
_LEVELS = 8
log = logging.getLogger("hnnbench")


def started_by_cli() -> bool:
    """Whether this process runs jobs for the ``hnnbench`` command (its own process
    under the basic launcher, or a launcher's worker), not for a caller of
    :func:`hnnbench._running.job.run_job` such as a notebook or a test, which is left alone."""
    return launch_context.current() is not None


def _pin_all_threads(cpu: int) -> None:
    """``sched_setaffinity`` acts per thread: pin the threads that exist already (thread
    pools started at import) and the calling one, whose children inherit it."""
    tasks = Path("/proc/self/task")
    tids = [int(p.name) for p in tasks.iterdir()] if tasks.is_dir() else []
    for tid in tids:
        try:
            os.sched_setaffinity(tid, {cpu})
        except OSError:  # a thread that ended meanwhile
            pass
    os.sched_setaffinity(0, {cpu})


def claim_core(lock_dir: Optional[Path] = None) -> Optional[int]:
    """Pin this process to one CPU, one that no other claimant holds if there is one;
    return it (``None``: not pinned, because the platform has no CPU affinity or the OS
    refused, e.g. an unwritable temporary directory; a warning says which).

    Idempotent: a process that holds a core returns it again.
    """
    try:
        return _claim(lock_dir)
    except OSError as err:
        log.warning(
            "hnnbench: could not pin this job to one CPU core (%s); it runs "
            "unpinned, and JAX results may then differ in the last bits",
            err,
        )
        return None


def _claim(lock_dir: Optional[Path]) -> Optional[int]:
    if "cpu" in _held:
        return int(_held["cpu"])  # type: ignore[call-overload]
    if not hasattr(os, "sched_setaffinity"):
        return None
    try:
        import fcntl  # noqa: F401 - the slots' locks
    except ImportError:  # not POSIX
        return None
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) == 1:
        _held["cpu"] = allowed[0]
        return allowed[0]
    directory = lock_dir or slots_dir("cpus")
    # Each core has _LEVELS slots (cpu<n>.lock, cpu<n>.2.lock, ...), one lock file each;
    # the least-held core is taken (hnnbench._running.slots).
    slots = {
        cpu: [
            f"cpu{cpu}.lock" if level == 1 else f"cpu{cpu}.{level}.lock"
            for level in range(1, _LEVELS + 1)
        ]
        for cpu in allowed
    }
    chosen, handle = claim_least_held(directory, slots)
    if chosen is None:  # every slot taken: share one
        cpu = allowed[os.getpid() % len(allowed)]
        _pin_all_threads(cpu)
        _held["cpu"] = cpu
        return cpu
    _pin_all_threads(chosen)
    _held.update(cpu=chosen, handle=handle)  # the lock lives as long as the process
    return chosen
