"""The sweep directory's lock: one sweep at a time writes into a directory."""

from __future__ import annotations

import contextlib
import json
import os
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Optional

from hnnbench import _record as records
from hnnbench._contracts import jsonio
from hnnbench._contracts.errors import HnnbenchError

__all__ = ["LOCK_NAME", "sweep_lock"]


#: The lock file of a sweep directory (held while a sweep runs into it).
LOCK_NAME = ".hnnbench.lock"


@contextlib.contextmanager
def sweep_lock(directory: Path, command: Optional[str] = None) -> Iterator[None]:
    """Hold ``<directory>/.hnnbench.lock`` (``flock``) while a sweep runs into it, with
    the holder's pid, host, start time and command written in it; raise a one-line
    :class:`HnnbenchError` naming the holder when another sweep holds it. The lock is
    the open file's: it goes when its process ends, however it ends, so a lock left by
    a killed sweep never blocks the next one. (No locking where ``fcntl`` is missing.)"""
    try:
        import fcntl
    except ImportError:  # Windows: no flock
        yield
        return
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / LOCK_NAME
    fh = open(path, "a+", encoding="utf-8")  # noqa: SIM115 - held for the whole sweep
    try:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            raise HnnbenchError(
                f"{directory} is in use by another sweep ({_holder(fh.read())}); wait for it "
                "to finish, or choose another hydra.sweep.dir (out= in the Python API)"
            ) from None
        fh.seek(0)
        fh.truncate()
        fh.write(
            json.dumps(
                {
                    "pid": os.getpid(),
                    "host": socket.gethostname(),
                    "started": records.now_iso(),
                    "command": command,
                }
            )
            + "\n"
        )
        fh.flush()
        try:
            yield
        finally:
            fh.seek(0)
            fh.truncate()
            fh.flush()
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    finally:
        fh.close()


def _holder(text: str) -> str:
    """``pid 123 on host, since <time>: <command>`` from a lock file's content."""
    try:
        info = jsonio.loads(text)
        assert isinstance(info, dict)
    except Exception:  # noqa: BLE001 - written in the middle, or by something else
        return "holder unknown"
    shown = f"pid {info.get('pid', '?')} on {info.get('host', '?')}"
    if info.get("started"):
        shown += f", since {info['started']}"
    if info.get("command"):
        shown += f": {info['command']}"
    return shown
