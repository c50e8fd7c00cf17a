"""joblib's worker processes (loky) may grow by :data:`WORKER_GROWTH` before they are
replaced (docs/SCALING.md, "Workers' memory").
"""

from __future__ import annotations

import logging
import os
import sys

log = logging.getLogger("hnnbench")

__all__ = ["WORKER_GROWTH", "WORKER_GROWTH_ENV", "set_worker_growth", "worker_growth"]


#: Memory (bytes) a joblib worker may gain over its first job before joblib's loky
#: replaces it with a new process. loky's own limit, 300 MB, is crossed within a few jobs
#: by a worker that imports its second backend and keeps each job's compiled JAX
#: programs (25-30 MB a job), and every replacement imports Hydra, torch and JAX again
#: (benchmarks/README.md, "joblib's worker replacement"). At this limit a worker is
#: replaced after some 60 JAX jobs, which still bounds its memory.
WORKER_GROWTH = 2_000_000_000
#: Environment variable: the limit in MB (10^6 bytes) instead of :data:`WORKER_GROWTH`
#: (300: loky's own).
WORKER_GROWTH_ENV = "HNNBENCH_WORKER_GROWTH_MB"
_growth_warned = False


def worker_growth() -> int:
    """The memory growth (bytes) a joblib worker is allowed: ``$HNNBENCH_WORKER_GROWTH_MB``
    or :data:`WORKER_GROWTH`; a bad value is reported in one line and the default used."""
    global _growth_warned
    text = os.environ.get(WORKER_GROWTH_ENV, "").strip()
    if not text:
        return WORKER_GROWTH
    try:
        megabytes = int(text)
    except ValueError:
        megabytes = 0
    if megabytes >= 1:
        return megabytes * 1_000_000
    if not _growth_warned:  # once per process, not once per job
        log.warning(
            "%s=%r is invalid: expected a whole number of megabytes >= 1 (300 is "
            "loky's own limit); using %d",
            WORKER_GROWTH_ENV,
            text,
            WORKER_GROWTH // 1_000_000,
        )
        _growth_warned = True
    return WORKER_GROWTH


def set_worker_growth() -> None:
    """Set loky's memory-growth limit to :func:`worker_growth` in this process, where a
    loky worker reads it after each task; nothing where loky is not loaded (any other
    launcher). loky declares no public setting for it."""
    module = sys.modules.get("joblib.externals.loky.process_executor")
    if module is not None and isinstance(getattr(module, "_MAX_MEMORY_LEAK_SIZE", None), int):
        module._MAX_MEMORY_LEAK_SIZE = worker_growth()  # type: ignore[attr-defined]
