"""Run records: one ``result.json`` per job, written atomically; loading a sweep.

Schema (``SCHEMA_VERSION``): see docs/ARCHITECTURE.md. Non-finite metric values are
written as JSON ``Infinity`` / ``NaN`` (Python's json reads them back).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import platform
import subprocess
import sys
import uuid
from collections.abc import Iterable, Iterator
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
    "atomic_path",
    "atomic_write_text",
    "environment",
    "load_records",
    "read_record",
    "write_record",
]


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; when the block succeeds, the file
    written there is synced to disk and renamed over ``path`` (``os.replace``), so
    ``path`` is always either the old complete file or the new one, never torn. The
    temporary name starts with a dot, contains ``.tmp`` and keeps ``path``'s suffix."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.{uuid.uuid4().hex}.tmp{path.suffix}")
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    finally:
        tmp.unlink(missing_ok=True)


def _fsync(path: Path) -> None:
    with open(path, "rb") as fh:
        os.fsync(fh.fileno())


def _fsync_dir(directory: Path) -> None:
    """Make a rename durable (POSIX); a no-op where directories cannot be opened."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)


def _json_default(value: Any) -> Any:
    """numpy scalars and arrays as numbers and lists (not strings); the rest as str."""
    if hasattr(value, "item") and getattr(value, "ndim", None) == 0:
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    return str(value)


def write_record(directory: Path, record: dict[str, Any]) -> Path:
    path = Path(directory) / RECORD_NAME
    atomic_write_text(path, json.dumps(record, indent=2, default=_json_default) + "\n")
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
    for dist in ("numpy", "scipy", "torch", "torchdiffeq", "safetensors", "jax", "jaxlib",
                 "equinox", "optax", "diffrax", "rebound", "hydra-core", "omegaconf", *extra):
        env[dist] = _version(dist)
    return env


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
