"""Slots held by file locks: each of several resources (CPU cores, GPUs) has a few slots,
one ``flock`` each, and a process takes a free slot of the least-held resource and holds
it while its lock file stays open. :mod:`hnnbench._running.affinity` (a core per job)
and :mod:`hnnbench._running.device_share` (a GPU slot per job) claim through it. POSIX
only (``fcntl``)."""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Optional

__all__ = ["claim_least_held", "slots_dir", "CLAIMING", "TURN_WAIT_S"]

#: The lock file of a slots directory that claimants take in turn while they count.
CLAIMING = ".claiming.lock"
#: Seconds a claimant waits for its turn to count before it counts anyway.
TURN_WAIT_S = 5.0


def slots_dir(kind: str) -> Path:
    """The directory of one kind of slot's lock files (``cpus``, ``gpus``): one per user
    under the temporary directory, shared by every process of that user."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = Path(tempfile.gettempdir()) / f"hnnbench-{kind}-{uid}"
    path.mkdir(parents=True, exist_ok=True)
    return path


def claim_least_held(
    directory: Path, slots: Mapping[int, Sequence[str]]
) -> tuple[Optional[int], Optional[IO[str]]]:
    """Take a free slot of the resource whose slots are least held (the lowest key on a
    tie): ``(key, the open lock file)``; closing the file frees the slot.
    ``slots``: each resource's lock-file names under ``directory``, in order. Every
    slot held: ``(None, None)``.

    Counting, not filling level by level: one free slot per resource is kept locked
    while counting (so no other claimant takes it meanwhile), and the others are let go
    once the least-held resource is chosen. With cores 0 and 1 held and a third claimant
    on core 0's second slot, once the first two exit the next claimant goes to core 1,
    not to core 0's free first slot. Claimants count one at a time (``CLAIMING``, a lock
    of the directory): two counting at once would each see the other's passing locks as
    holders and could both choose the same resource. A claimant waits at most
    :data:`TURN_WAIT_S` for its turn (the counter stopped, say by ``SIGSTOP``), then
    counts anyway.
    """
    import fcntl

    with open(directory / CLAIMING, "a+") as turn:  # the lock goes when the file closes
        deadline = time.monotonic() + TURN_WAIT_S
        while True:
            try:
                fcntl.flock(turn, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.01)
            except OSError:  # no locks on this file system: every slot will read as held
                break
        return _count_and_claim(directory, slots)


def _count_and_claim(
    directory: Path, slots: Mapping[int, Sequence[str]]
) -> tuple[Optional[int], Optional[IO[str]]]:
    """:func:`claim_least_held`'s count and choice, run by one claimant at a time."""
    import fcntl

    held = dict.fromkeys(slots, 0)
    free: dict[int, IO[str]] = {}
    try:
        for key, names in slots.items():
            for name in names:
                handle: IO[str] = open(directory / name, "a+")  # noqa: SIM115
                try:
                    fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError:
                    held[key] += 1
                    handle.close()
                    continue
                if key in free:  # a second free slot of this resource: not needed
                    handle.close()
                else:
                    free[key] = handle
    except OSError:  # a lock file that cannot be opened: let go of the slots kept so far
        for handle in free.values():
            handle.close()
        raise
    if not free:
        return None, None
    chosen = min(free, key=lambda k: (held[k], k))
    for other, handle in free.items():
        if other != chosen:
            handle.close()  # closing releases the lock
    return chosen, free[chosen]
