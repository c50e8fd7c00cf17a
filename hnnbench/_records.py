"""Run records: one ``result.json`` per job, written atomically and checked against
the record's JSON Schema; the one loader of records, :func:`load`.

The record is defined in :mod:`hnnbench._record_schema` (its fields; the JSON Schema
:func:`schema` and the shipped ``hnnbench/resources/record.schema.json`` are made from
that). It is strict JSON (any parser reads it). Non-finite numbers are encoded: ``inf``
and ``-inf`` as the strings ``"inf"`` / ``"-inf"``, NaN ("not applicable", "undefined")
as ``null``. :func:`read_record` decodes them back to floats in ``metrics`` and
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
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

from hnnbench._errors import HnnbenchError
from hnnbench._record_schema import (
    LOADER_FIELDS,
    SCHEMA_VERSION,
    STATUSES,
    json_schema,
    shape_problems,
)

RECORD_NAME = "result.json"
#: A job's arrays (rollouts, true states, training history) beside its record.
ROLLOUT_NAME = "rollout.npz"
#: Statuses of a job that is done and is not redone on resume.
FINISHED = ("ok", "diverged", "skipped")
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
    "InvalidRecord",
    "Loaded",
    "Unreadable",
    "atomic_path",
    "atomic_write_text",
    "decode",
    "encode",
    "environment",
    "load",
    "load_records",
    "read_record",
    "scan_records",
    "schema",
    "strict_problems",
    "validate",
    "write_record",
]


class InvalidRecord(HnnbenchError):
    """A record that does not conform to the record's JSON Schema was not written."""


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
    """Write ``record`` as strict JSON to ``directory/result.json``, atomically, after
    checking it against the record's JSON Schema: a record that does not conform is not
    written (:class:`InvalidRecord`, naming the field)."""
    path = Path(directory) / RECORD_NAME
    data = encode({k: v for k, v in record.items() if k not in LOADER_FIELDS})
    problems = _schema_problems(data)
    if problems:
        raise InvalidRecord(f"refusing to write {path}: invalid record: {problems[0]}")
    text = json.dumps(data, indent=2, allow_nan=False)
    atomic_write_text(path, text + "\n")
    return path


def _parse(path: Path) -> dict[str, Any] | str:
    """The JSON object at ``path``, or why there is none (one line)."""
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
    except OSError as err:
        return f"cannot read it ({err.strerror})"
    except ValueError as err:
        return f"not valid JSON ({err})"
    return data if isinstance(data, dict) else "not a JSON object"


def read_record(path: Path) -> dict[str, Any] | None:
    """The record at ``path`` (decoded), or ``None`` if missing or unreadable (a job
    reads its own earlier record with it, on resume). Not checked: :func:`load` is
    what reads records for their results."""
    record = _parse(path)
    if isinstance(record, str) or "status" not in record:
        return None
    return decode(record)


@dataclass(frozen=True)
class Unreadable:
    """A ``result.json`` that could not be read, or is not a valid record, and why."""

    path: Path
    reason: str

    def __str__(self) -> str:
        return f"{self.path}: {self.reason}"


@dataclass(frozen=True)
class Loaded:
    """What :func:`load` found: the records, and the files left out (each with its
    one-line reason). Unpacks as ``records, problems = load(...)``."""

    records: list[dict[str, Any]] = field(default_factory=list)
    problems: list[Unreadable] = field(default_factory=list)

    def __iter__(self) -> Iterator[Any]:
        return iter((self.records, self.problems))


def load(*directories: Path | str, strict: bool = False) -> Loaded:
    """The records below the directories (every ``result.json``; several directories
    merge), each with ``"path"`` (its directory) and ``"source"`` (the directory it was
    found under) added, and the files left out, with why.

    A file is left out when it cannot be read, is not a JSON object, or is not usable
    as a record (:func:`hnnbench._record_schema.shape_problems`: a required field
    missing, a field of the wrong type); ``strict`` also leaves out every record that
    does not pass :func:`strict_problems` (the JSON Schema in full: what ``hnnbench
    check`` and publishing need). A directory that does not exist holds no records.
    """
    out = Loaded()
    for directory in directories:
        for path in sorted(Path(directory).rglob(RECORD_NAME)):
            if path.name.startswith("."):
                continue
            record = _parse(path)
            if isinstance(record, str):
                out.problems.append(Unreadable(path, record))
                continue
            problems = shape_problems(record)
            if not problems:
                record = decode(record)
                problems = strict_problems(record) if strict else []
            if problems:
                out.problems.append(Unreadable(path, f"invalid record: {problems[0]}"))
                continue
            record["path"] = str(path.parent)
            record["source"] = str(directory)
            out.records.append(record)
    return out


def scan_records(*directories: Path | str) -> tuple[list[dict[str, Any]], list[Unreadable]]:
    """``(records, problems)`` of :func:`load` (not strict)."""
    loaded = load(*directories)
    return loaded.records, loaded.problems


def load_records(*directories: Path | str) -> list[dict[str, Any]]:
    """The records of :func:`load` (not strict)."""
    return load(*directories).records


def schema() -> dict[str, Any]:
    """The record's JSON Schema (:func:`hnnbench._record_schema.json_schema`; shipped
    as ``hnnbench/resources/record.schema.json``)."""
    return dict(_validator().schema)


@lru_cache(maxsize=1)
def _validator() -> Any:
    import jsonschema

    return jsonschema.Draft202012Validator(json_schema())


def _schema_problems(data: Any) -> list[str]:
    """The JSON Schema violations of encoded record data, one line each naming the
    field (``a.b: ...``; a missing field: ``'a' is a required property``)."""
    validator = _validator()
    if validator.is_valid(data):
        return []
    out = []
    for err in sorted(validator.iter_errors(data), key=lambda e: list(map(str, e.absolute_path))):
        where = ".".join(str(p) for p in err.absolute_path)
        out.append(f"{where}: {err.message}" if where else err.message)
    return out


def validate(record: dict[str, Any]) -> list[str]:
    """Schema violations of ``record`` (one line each; empty: valid). Fields the loader
    adds (``path``, ``source``) are ignored."""
    return _schema_problems(encode({k: v for k, v in record.items()
                                    if k not in LOADER_FIELDS}))


#: The checks of a strict load, in order (each: a decoded record -> its problems, one
#: line each). Further checks of submitted records (bounds on sizes, the domains of metric
#: values) go here.
STRICT_CHECKS: tuple[Callable[[dict[str, Any]], list[str]], ...] = (validate,)


def strict_problems(record: dict[str, Any]) -> list[str]:
    """What a strict :func:`load` finds wrong with ``record`` (one line each; empty:
    none): every check of :data:`STRICT_CHECKS`."""
    return [problem for check in STRICT_CHECKS for problem in check(record)]


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
