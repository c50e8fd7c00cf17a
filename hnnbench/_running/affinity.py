"""One CPU core per job process (:func:`claim_core`: a ``flock`` per core, every thread
pinned before any JAX computation), so that XLA runs one thread and every launcher gives
the same numbers (docs/SCALING.md, "One thread per job"). Linux only.
"""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path
from typing import IO, Optional

from hnnbench._running import launch_context

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


def _lock_dir() -> Path:
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = Path(tempfile.gettempdir()) / f"hnnbench-cpus-{uid}"
    path.mkdir(parents=True, exist_ok=True)
    return path


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
        import fcntl
    except ImportError:  # not POSIX
        return None
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) == 1:
        _held["cpu"] = allowed[0]
        return allowed[0]
    directory = lock_dir or _lock_dir()
    # Each core has _LEVELS slots (cpu<n>.lock, cpu<n>.2.lock, ...), one lock file each.
    # Count every core's holders and keep one free slot per core while counting (so no
    # other claimant takes it meanwhile); take the least-held core (the lowest on a tie)
    # and let the other slots go. Counting, not filling level by level: with cores 0
    # and 1 held and a third claimant on core 0's second slot, once the first two exit
    # the next claimant goes to core 1, not to core 0's free first slot.
    holders = dict.fromkeys(allowed, 0)
    free: dict[int, IO[str]] = {}
    for cpu in allowed:
        for level in range(1, _LEVELS + 1):
            name = f"cpu{cpu}.lock" if level == 1 else f"cpu{cpu}.{level}.lock"
            handle: IO[str] = open(directory / name, "a+")  # noqa: SIM115
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holders[cpu] += 1
                handle.close()
                continue
            if cpu in free:  # a second free slot of this core: not needed
                handle.close()
            else:
                free[cpu] = handle
    if not free:  # every slot taken: share one
        cpu = allowed[os.getpid() % len(allowed)]
        _pin_all_threads(cpu)
        _held["cpu"] = cpu
        return cpu
    cpu = min(free, key=lambda c: (holders[c], c))
    for other, handle in free.items():
        if other != cpu:
            handle.close()  # closing releases the lock
    _pin_all_threads(cpu)
    _held.update(cpu=cpu, handle=free[cpu])  # the lock lives as long as the process
    return cpu
