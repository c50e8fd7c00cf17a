"""One CPU core per launcher worker.

A job runs its networks with one thread (``threads=1``), but XLA's CPU thread pool still
spreads large products over every core it may use, so two parallel workers on a 2-core
machine contend (docs/SCALING.md). :func:`claim_core` gives the calling process a core of
its own: it takes an exclusive ``flock`` on one lock file per allowed CPU, in order, and
pins every thread of the process to the first CPU whose lock it gets. The lock is held
until the process exits, so concurrent workers (joblib/loky processes, submitit tasks,
even two sweeps) end up on different cores, and a reused worker keeps its core.

Linux only; elsewhere, or with a single allowed CPU, nothing is pinned.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import IO, Optional

__all__ = ["claim_core", "is_launcher_worker", "MAIN_PID_ENV"]

#: Set by the CLI to the pid of the process that starts Hydra; launcher workers inherit it.
MAIN_PID_ENV = "HNNBENCH_MAIN_PID"

_held: dict[str, object] = {}


def is_launcher_worker() -> bool:
    """Whether this process is a launcher's worker, not the ``hnnbench`` process itself
    (the basic launcher runs jobs in the main process; joblib and submitit do not)."""
    main = os.environ.get(MAIN_PID_ENV)
    return main is not None and main != str(os.getpid())


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
    """Pin this process to a CPU no other claimant holds; return it (``None``: not
    pinned, because the platform can't, one CPU is allowed, or every core is taken).

    Idempotent: a process that holds a core returns it again.
    """
    if "cpu" in _held:
        return int(_held["cpu"])  # type: ignore[call-overload]
    if not hasattr(os, "sched_setaffinity"):
        return None
    try:
        import fcntl
    except ImportError:  # not POSIX
        return None
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) < 2:
        return None
    directory = lock_dir or _lock_dir()
    for cpu in allowed:
        handle: IO[str] = open(directory / f"cpu{cpu}.lock", "a+")  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _pin_all_threads(cpu)
        _held.update(cpu=cpu, handle=handle)  # the lock lives as long as the process
        return cpu
    return None
