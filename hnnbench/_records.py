"""Run records: one ``result.json`` per job, written atomically; loading sweeps.

The record is strict JSON (any parser reads it), described by the JSON Schema
``hnnbench/resources/record.schema.json`` (:func:`schema`, :func:`validate`;
docs/ARCHITECTURE.md lists the fields). Non-finite numbers are encoded: ``inf`` and
``-inf`` as the strings ``"inf"`` / ``"-inf"``, NaN ("not applicable", "undefined") as
``null``. :func:`read_record` decodes them back to floats in ``metrics`` and
``history``. Records of schema version 1 (bare ``NaN`` / ``Infinity``) are still read.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import platform
import subprocess
import sys
import uuid
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

SCHEMA_VERSION = 2
RECORD_NAME = "result.json"
#: A job's arrays (rollouts, true states, training history) beside its record.
ROLLOUT_NAME = "rollout.npz"
SCHEMA_FILE = "record.schema.json"
#: Statuses of a job that is done and is not redone on resume.
FINISHED = ("ok", "diverged", "skipped")
STATUSES = ("ok", "diverged", "failed", "skipped", "timeout")
#: Top-level config keys that say where and how a job runs, not what it computes: a
#: finished record is reused on resume whatever they are, they define no leaderboard
#: variant, and they are left out of a sweep job's directory name (conf/config.yaml's
#: ``override_dirname.exclude_keys``, which tests/test_config.py holds to this list).
RUN_ONLY_KEYS = frozenset({
    "rerun", "device", "threads", "pin_cpu", "save_model", "cache_dir", "data_dir",
    "seeds_per_job", "seed_batch", "timeout_s",
})

__all__ = [
    "FINISHED",
    "RUN_ONLY_KEYS",
    "RECORD_NAME",
    "ROLLOUT_NAME",
    "SCHEMA_VERSION",
    "STATUSES",
    "Unreadable",
    "atomic_path",
    "atomic_write_text",
    "decode",
    "encode",
    "environment",
    "load_records",
    "read_record",
    "scan_records",
    "schema",
    "validate",
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


def encode(value: Any) -> Any:
    """``value`` as strict JSON data: numpy types as Python ones, ``inf`` as ``"inf"``,
    NaN as ``None``, recursively."""
    if isinstance(value, dict):
        return {str(k): encode(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [encode(v) for v in value]
    if hasattr(value, "item") and getattr(value, "ndim", None) == 0:
        value = value.item()
    elif hasattr(value, "tolist"):
        return encode(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return str(value)


def _number(value: Any) -> Any:
    if value is None:
        return math.nan
    if value in ("inf", "-inf", "Infinity", "-Infinity", "NaN", "nan"):
        return float(value)
    return value


def decode(record: dict[str, Any]) -> dict[str, Any]:
    """Turn the encoded non-finite values of ``metrics`` and ``history`` back into
    floats (in place; returns ``record``)."""
    for metric in (record.get("metrics") or {}).values():
        if isinstance(metric, dict):
            for key in ("mean", "sem"):
                if key in metric:
                    metric[key] = _number(metric[key])
    history = record.get("history")
    if isinstance(history, dict):
        for key, values in history.items():
            if isinstance(values, list):
                history[key] = [_number(v) for v in values]
    return record


def write_record(directory: Path, record: dict[str, Any]) -> Path:
    """Write ``record`` as strict JSON to ``directory/result.json``, atomically."""
    path = Path(directory) / RECORD_NAME
    text = json.dumps(encode(record), indent=2, allow_nan=False)
    atomic_write_text(path, text + "\n")
    return path


def read_record(path: Path) -> dict[str, Any] | None:
    """The record at ``path`` (decoded), or ``None`` if missing or unreadable."""
    try:
        with open(path, encoding="utf-8") as fh:
            record = json.load(fh)
    except (OSError, ValueError):
        return None
    if not (isinstance(record, dict) and "status" in record):
        return None
    return decode(record)


@dataclass(frozen=True)
class Unreadable:
    """A ``result.json`` that could not be read, and why."""

    path: Path
    reason: str

    def __str__(self) -> str:
        return f"{self.path}: {self.reason}"


def _why_unreadable(path: Path) -> str:
    try:
        with open(path, encoding="utf-8") as fh:
            record = json.load(fh)
    except OSError as err:
        return f"cannot read it ({err.strerror})"
    except ValueError as err:
        return f"not valid JSON ({err})"
    return "not a run record (no 'status' field)" if isinstance(record, dict) else \
        "not a JSON object"


def scan_records(*directories: Path | str) -> tuple[list[dict[str, Any]], list[Unreadable]]:
    """Every record below each directory (each with ``"path"`` set, and ``"source"``:
    the directory it was found under), and the files that could not be read."""
    out: list[dict[str, Any]] = []
    bad: list[Unreadable] = []
    for directory in directories:
        for path in sorted(Path(directory).rglob(RECORD_NAME)):
            if path.name.startswith("."):
                continue
            record = read_record(path)
            if record is None:
                bad.append(Unreadable(path, _why_unreadable(path)))
                continue
            record["path"] = str(path.parent)
            record["source"] = str(directory)
            out.append(record)
    return out, bad


def load_records(*directories: Path | str) -> list[dict[str, Any]]:
    """All readable records below the directories (see :func:`scan_records`)."""
    return scan_records(*directories)[0]


@lru_cache(maxsize=1)
def schema() -> dict[str, Any]:
    """The record's JSON Schema (``hnnbench/resources/record.schema.json``)."""
    from importlib import resources

    text = resources.files("hnnbench").joinpath("resources", SCHEMA_FILE).read_text("utf-8")
    return dict(json.loads(text))


def validate(record: dict[str, Any]) -> list[str]:
    """Schema violations of ``record`` (one line each; empty: valid). Fields the loader
    adds (``path``, ``source``) are ignored."""
    import jsonschema

    data = encode({k: v for k, v in record.items() if k not in ("path", "source")})
    validator = jsonschema.Draft202012Validator(schema())
    out = []
    for err in sorted(validator.iter_errors(data), key=lambda e: list(e.absolute_path)):
        where = ".".join(str(p) for p in err.absolute_path) or "(record)"
        out.append(f"{where}: {err.message}")
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
        if out.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
            capture_output=True, text=True, timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):  # no git, or a slow one: not recorded
        return None
    return out.stdout.strip() + ("-dirty" if dirty else "")


def environment(extra: Iterable[str] = ()) -> dict[str, Any]:
    """Versions and platform, for reproducing a record."""
    env: dict[str, Any] = {
        "hnnbench": _version("hnnbench"),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "machine": platform.machine(),
        "host": platform.node(),
        "git_commit": git_commit(),
    }
    for dist in ("numpy", "scipy", "torch", "torchdiffeq", "safetensors", "jax", "jaxlib",
                 "equinox", "optax", "diffrax", "rebound", "hydra-core", "omegaconf", *extra):
        env[dist] = _version(dist)
    return env


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
