"""Run records: one ``result.json`` per job, written atomically; loading a sweep.

Schema (``SCHEMA_VERSION``): see docs/ARCHITECTURE.md. Non-finite metric values are
written as JSON ``Infinity`` / ``NaN`` (Python's json reads them back).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import subprocess
import sys
import uuid
from collections.abc import Iterable
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

SCHEMA_VERSION = 1
RECORD_NAME = "result.json"
#: Statuses of a job that is done and is not redone on resume.
FINISHED = ("ok", "diverged", "skipped")
STATUSES = ("ok", "diverged", "failed", "skipped")

__all__ = [
    "FINISHED",
    "RECORD_NAME",
    "SCHEMA_VERSION",
    "STATUSES",
    "atomic_write_text",
    "environment",
    "load_records",
    "read_record",
    "write_record",
]


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and ``os.replace``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_record(directory: Path, record: dict[str, Any]) -> Path:
    path = directory / RECORD_NAME
    atomic_write_text(path, json.dumps(record, indent=2, sort_keys=False, default=str) + "\n")
    return path


def read_record(path: Path) -> dict[str, Any] | None:
    """The record at ``path``, or ``None`` if missing or unreadable."""
    try:
        with open(path, encoding="utf-8") as fh:
            record = json.load(fh)
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and "status" in record else None


def load_records(directory: Path) -> list[dict[str, Any]]:
    """All readable records below ``directory``, each with ``"path"`` set."""
    out = []
    for path in sorted(Path(directory).rglob(RECORD_NAME)):
        record = read_record(path)
        if record is not None:
            record["path"] = str(path.parent)
            out.append(record)
    return out


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


@lru_cache(maxsize=1)
def git_commit() -> str | None:
    """The commit of the hnnbench source tree, if it is a git checkout."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5
        )
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
        capture_output=True, text=True, timeout=5,
    ).stdout.strip()
    return out.stdout.strip() + ("-dirty" if dirty else "")


def environment(extra: Iterable[str] = ()) -> dict[str, Any]:
    """Versions and platform, for reproducing a record."""
    env: dict[str, Any] = {
        "hnnbench": _version("hnnbench"),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "machine": platform.machine(),
        "git_commit": git_commit(),
    }
    for dist in ("numpy", "scipy", "torch", "jax", "jaxlib", "diffrax", "rebound", *extra):
        env[dist] = _version(dist)
    return env


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
