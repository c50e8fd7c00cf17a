"""Run records: one ``result.json`` per job, written atomically and checked against
the record's JSON Schema; the one loader of records, :func:`load`.

The record is defined in :mod:`hnnbench._record_schema` (its fields; the JSON Schema
:func:`schema` and the shipped ``hnnbench/resources/record.schema.json`` are made from
that). It is strict JSON (any parser reads it). Non-finite numbers are encoded: ``inf``
and ``-inf`` as the strings ``"inf"`` / ``"-inf"``, NaN ("not applicable", "undefined")
as ``null``. :func:`read_record` decodes them back to floats in ``metrics`` and
``history``. Records of schema version 1 (bare ``NaN`` / ``Infinity``) are still read.

Records may come from someone else's machine (docs/LEADERBOARD.md, "Threat model"), so
reading one is bounded: a ``result.json`` that is not a regular file (a symbolic link, a
device, a pipe) or is larger than :data:`hnnbench._record_schema.MAX_RECORD_BYTES` is
refused before it is read, JSON nested deeper than
:data:`~hnnbench._record_schema.MAX_DEPTH` before the schema sees it, and every file that
cannot be read or is not a record is left out with a one-line reason naming the field,
while the others load. A strict load also holds the record to its format (``created_at``
an RFC 3339 date-time, not in the future) and each metric's mean to its declared
domain (:attr:`hnnbench._metric.Metric.domain`). A rollout (:func:`load_arrays`) is read
only when its declared, decompressed size is bounded and it holds no objects.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import json
import math
import os
import platform
import stat
import subprocess
import sys
import uuid
import zipfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from functools import cache, lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

from hnnbench._errors import HnnbenchError
from hnnbench._record_schema import (
    LOADER_FIELDS,
    MAX_DEPTH,
    MAX_RECORD_BYTES,
    SCHEMA_VERSION,
    STATUSES,
    created_at_problem,
    history_problems,
    is_date_time,
    json_schema,
    shape_problems,
)

RECORD_NAME = "result.json"
#: A job's arrays (rollouts, true states, training history) beside its record.
ROLLOUT_NAME = "rollout.npz"
#: The largest rollout read (:func:`load_arrays`): its arrays' total decompressed size as
#: declared, in bytes (a job's rollouts are a few MB).
MAX_ROLLOUT_BYTES = 256 * 1024 * 1024
#: Statuses of a job that is done and is not redone on resume.
FINISHED = ("ok", "diverged", "skipped")
#: Top-level config keys that say where and how a job runs, not what it computes: a
#: finished record is reused on resume whatever they are, they define no leaderboard
#: variant, and they are left out of a sweep job's directory name (conf/config.yaml's
#: ``override_dirname.exclude_keys``, which tests/test_config.py holds to this list).
RUN_ONLY_KEYS = frozenset({
    "rerun", "device", "threads", "pin_cpu", "save_model", "cache_dir", "data_dir",
    "seeds_per_job", "seed_batch", "timeout_s", "log_to", "mlflow_uri",
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
    "UnsafeFile",
    "Unreadable",
    "atomic_path",
    "atomic_write_text",
    "decode",
    "encode",
    "environment",
    "load",
    "load_arrays",
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
    problems = shape_problems(data) or _depth_problems(data) or _schema_problems(data)
    if problems:
        raise InvalidRecord(f"refusing to write {path}: invalid record: {problems[0]}")
    text = json.dumps(data, indent=2, allow_nan=False)
    atomic_write_text(path, text + "\n")
    return path


class UnsafeFile(HnnbenchError):
    """A file that is not read: not a regular file, or over its size limit."""


@contextlib.contextmanager
def open_regular(path: Path | str, limit: int) -> Iterator[Any]:
    """``path`` opened for reading (binary), if it is a regular file of at most ``limit``
    bytes that is not a symbolic link: never a link out of its directory, a device
    (``/dev/zero``), a pipe or a file that would take long to read. Raises
    :class:`UnsafeFile` (or ``OSError`` where it cannot be opened) with the reason."""
    path = Path(path)
    if path.is_symlink():
        raise UnsafeFile("it is a symbolic link (not followed)")
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) \
        | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as err:
        if err.errno == errno.ELOOP:  # replaced by a link since the check
            raise UnsafeFile("it is a symbolic link (not followed)") from None
        raise
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise UnsafeFile("it is not a regular file (not read)")
        if info.st_size > limit:
            raise UnsafeFile(f"it is {info.st_size} bytes, over the limit of {limit} "
                             "(not read)")
        fh = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with fh:
        yield fh


def _read_bounded(path: Path, limit: int) -> bytes | UnsafeFile:
    """The bytes of ``path`` (:func:`open_regular`; at most ``limit + 1`` bytes are ever
    read, in case the file grows), or why not."""
    try:
        with open_regular(path, limit) as fh:
            data: bytes = fh.read(limit + 1)
    except UnsafeFile as err:
        return err
    except OSError as err:
        return UnsafeFile(f"cannot read it ({err.strerror or err})")
    if len(data) > limit:
        return UnsafeFile(f"it grew over the limit of {limit} bytes while read")
    return data


def _depth_problems(data: Any, limit: int = MAX_DEPTH) -> list[str]:
    """``["nested deeper than ..."]`` when objects and arrays in ``data`` nest more than
    ``limit`` levels (checked without recursion), else ``[]``."""
    level: list[tuple[Any, int]] = [(data, 1)]
    while level:
        value, depth = level.pop()
        children = value.values() if isinstance(value, dict) else \
            value if isinstance(value, list) else None
        if children is None:
            continue
        if depth > limit:
            return [f"JSON nested deeper than {limit} levels"]
        level.extend((child, depth + 1) for child in children
                     if isinstance(child, (dict, list)))
    return []


def _parse(path: Path) -> dict[str, Any] | str:
    """The JSON object at ``path``, or why there is none (one line): read bounded
    (:func:`_read_bounded`), valid UTF-8 JSON, an object, nested at most
    :data:`~hnnbench._record_schema.MAX_DEPTH` levels."""
    raw = _read_bounded(path, MAX_RECORD_BYTES)
    if isinstance(raw, UnsafeFile):
        return str(raw)
    try:
        data = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        return "not valid JSON (not UTF-8 text)"
    except RecursionError:
        return f"not a record: JSON nested deeper than {MAX_DEPTH} levels"
    except ValueError as err:
        return f"not valid JSON ({' '.join(str(err).split())[:200]})"
    if not isinstance(data, dict):
        return "not a JSON object"
    depth = _depth_problems(data)
    return f"not a record: {depth[0]}" if depth else data


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

    A file is left out when it cannot be read (not a regular file, a symbolic link,
    larger than :data:`~hnnbench._record_schema.MAX_RECORD_BYTES`), is not a JSON object
    (or nests deeper than :data:`~hnnbench._record_schema.MAX_DEPTH`), or is not usable
    as a record (:func:`hnnbench._record_schema.shape_problems`: a required field
    missing, a field of the wrong type, a name that is not a name); ``strict`` also
    leaves out every record that does not pass :func:`strict_problems` (the JSON Schema
    in full, ``created_at`` not in the future, each metric within its declared domain:
    what ``hnnbench check`` and publishing need). Each file left out is named with the
    first reason, in one line; the others load. A directory that does not exist holds
    no records.
    """
    out = Loaded()
    for directory in directories:
        for path in sorted(Path(directory).rglob(RECORD_NAME)):
            if path.name.startswith("."):
                continue
            try:
                record = _load_one(path, strict)
            except Exception as err:  # noqa: BLE001 - one bad file never stops the others
                record = f"invalid record: cannot be checked ({type(err).__name__}: " \
                         f"{' '.join(str(err).split())[:200]})"
            if isinstance(record, str):
                out.problems.append(Unreadable(path, record))
                continue
            record["path"] = str(path.parent)
            record["source"] = str(directory)
            out.records.append(record)
    return out


def _load_one(path: Path, strict: bool) -> dict[str, Any] | str:
    """The record at ``path`` (decoded), or why it is left out (one line)."""
    record = _parse(path)
    if isinstance(record, str):
        return record
    problems = shape_problems(record)
    if not problems and strict:
        problems = _schema_problems(record)  # the JSON as read: nothing to encode
    if not problems:
        record = decode(record)
        problems = _decoded_problems(record) if strict else []
    if problems:
        return f"invalid record: {problems[0]}"
    return record


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

    # The schema's "format" is enforced, by hnnbench's own check (jsonschema's needs an
    # optional package, and without it passes any string).
    formats = jsonschema.FormatChecker(formats=())
    formats.checks("date-time")(is_date_time)
    return jsonschema.Draft202012Validator(json_schema(), format_checker=formats)


def _schema_problems(data: Any) -> list[str]:
    """The JSON Schema violations of encoded record data, one line each naming the
    field (``a.b: ...``; a missing field: ``'a' is a required property``). The training
    history is checked by a loop (:func:`~hnnbench._record_schema.history_problems`),
    the rest by jsonschema."""
    if not isinstance(data, dict):
        return [f"{type(data).__name__} is not of type 'object'"]
    validator = _validator()
    rest = {k: v for k, v in data.items() if k != "history"}
    out = []
    if not validator.is_valid(rest):
        for err in sorted(validator.iter_errors(rest),
                          key=lambda e: list(map(str, e.absolute_path))):
            where = ".".join(str(p) for p in err.absolute_path)
            message = " ".join(str(err.message).split())
            message = message if len(message) <= 300 else message[:297] + "..."
            out.append(f"{where}: {message}" if where else message)
    if "history" in data:
        out += history_problems(data["history"])
    return out


def validate(record: dict[str, Any]) -> list[str]:
    """Schema violations of ``record`` (one line each; empty: valid). Fields the loader
    adds (``path``, ``source``) are ignored."""
    data = encode({k: v for k, v in record.items() if k not in LOADER_FIELDS})
    return _depth_problems(data) or _schema_problems(data)


def created_at_problems(record: dict[str, Any]) -> list[str]:
    """``created_at`` an RFC 3339 date-time that is not in the future
    (:func:`hnnbench._record_schema.created_at_problem`)."""
    if "created_at" not in record:
        return []  # a required field: the schema names it
    problem = created_at_problem(record["created_at"])
    return [problem] if problem else []


def metric_domain_problems(record: dict[str, Any]) -> list[str]:
    """Each metric's mean within its declared domain and its sem a standard error
    (:meth:`hnnbench._metric.Metric.value_problem`); a metric no installed plugin
    declares is held to a standard error only."""
    from hnnbench import _registry as registry
    from hnnbench._metric import Metric

    declared = {m.name: m for m in registry.metrics()}
    for name, value in (record.get("metrics") or {}).items():
        if not isinstance(value, dict):
            continue  # the schema names it
        metric = declared.get(name) or Metric(name, "", lambda ctx: None)
        mean, sem = value.get("mean", math.nan), value.get("sem", math.nan)
        problem = metric.value_problem(math.nan if mean is None else mean,
                                       math.nan if sem is None else sem)
        if problem:
            return [f"metrics.{name}: {problem}"]
    return []


#: The checks of a strict load after the JSON Schema, in order (each: a decoded record
#: -> its problems, one line each).
STRICT_CHECKS: tuple[Callable[[dict[str, Any]], list[str]], ...] = (
    created_at_problems, metric_domain_problems)


def _decoded_problems(record: dict[str, Any]) -> list[str]:
    for check in STRICT_CHECKS:
        problems = check(record)
        if problems:
            return problems
    return []


def strict_problems(record: dict[str, Any]) -> list[str]:
    """What a strict :func:`load` finds wrong with ``record`` (decoded; one line each;
    empty: none): the JSON Schema (:func:`validate`), then the checks of
    :data:`STRICT_CHECKS`."""
    return validate(record) or _decoded_problems(record)


def load_arrays(path: Path | str, limit: int | None = None) -> dict[str, Any]:
    """The arrays of a rollout file (``.npz``), read bounded: a regular file
    (:func:`open_regular`), whose members' declared decompressed sizes add up to at most
    ``limit`` bytes (default :data:`MAX_ROLLOUT_BYTES`), each a ``.npy`` array of plain
    numbers whose header's shape fits the member (so no decompression bomb, no huge
    allocation) and no objects (never unpickled). Raises :class:`UnsafeFile` (or
    ``OSError``, ``ValueError``, ``zipfile.BadZipFile``) with the reason."""
    import numpy as np
    from numpy.lib import format as npy

    limit = MAX_ROLLOUT_BYTES if limit is None else limit
    out: dict[str, Any] = {}
    with open_regular(path, limit) as fh, zipfile.ZipFile(fh) as zf:
        members = zf.infolist()
        declared = sum(m.file_size for m in members)
        if declared > limit:
            raise UnsafeFile(f"its arrays would take {declared} bytes decompressed, over "
                             f"the limit of {limit} (not read)")
        for member in members:
            if not member.filename.endswith(".npy"):
                continue
            with zf.open(member) as raw:
                version = npy.read_magic(raw)
                if version not in ((1, 0), (2, 0)):
                    raise UnsafeFile(f"{member.filename}: .npy format {version} is not "
                                     "read")
                header = npy.read_array_header_1_0 if version == (1, 0) else \
                    npy.read_array_header_2_0
                shape, _, dtype = header(raw)
                if dtype.hasobject:
                    raise UnsafeFile(f"{member.filename} holds objects (not read)")
                size = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                if size > member.file_size:
                    raise UnsafeFile(f"{member.filename} declares {size} bytes of data in "
                                     f"a member of {member.file_size} (not read)")
            with zf.open(member) as raw:
                out[member.filename[:-4]] = npy.read_array(raw, allow_pickle=False)
    return out


@cache
def _version(dist: str) -> str | None:
    """The installed version of ``dist`` (read once per process: 14 metadata lookups
    were ~80 ms of every job's record)."""
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
