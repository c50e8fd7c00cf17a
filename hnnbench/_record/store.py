"""Record files: written atomically and only when valid, read bounded (regular files,
size, nesting), strict JSON with non-finite numbers encoded; rollout arrays read
bounded (docs/LEADERBOARD.md, "Threat model").
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import stat
import uuid
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hnnbench._contracts import jsonio
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._contracts.names import LOADER_FIELDS, one_line
from hnnbench._record.codec import MAX_DEPTH, decode, depth_problems, encode
from hnnbench._record.fields import RECORD_NAME
from hnnbench._record.validation import (
    schema_problems,
    shape_problems,
)

__all__ = [
    "InvalidRecord",
    "MAX_RECORD_BYTES",
    "MAX_ROLLOUT_BYTES",
    "UnsafeFile",
    "atomic_path",
    "atomic_write_text",
    "load_arrays",
    "open_regular",
    "read_record",
    "write_record",
]


#: The largest ``result.json`` read (bytes): a record is a few to a few hundred KB (its
#: training history is the bulk); a larger file is refused before it is parsed.
MAX_RECORD_BYTES = 2 * 1024 * 1024
#: The largest rollout read (:func:`load_arrays`): its arrays' total decompressed size as
#: declared, in bytes (a job's rollouts are a few MB).
MAX_ROLLOUT_BYTES = 256 * 1024 * 1024


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


def write_record(directory: Path, record: dict[str, Any]) -> Path:
    """Write ``record`` as strict JSON to ``directory/result.json``, atomically, after
    checking it against the record's JSON Schema: a record that does not conform is not
    written (:class:`InvalidRecord`, naming the field)."""
    path = Path(directory) / RECORD_NAME
    data = encode({k: v for k, v in record.items() if k not in LOADER_FIELDS})
    problems = shape_problems(data) or depth_problems(data) or schema_problems(data)
    if problems:
        raise InvalidRecord(
            one_line(f"refusing to write {path}: invalid record: {problems[0]}", 2000)
        )
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
    flags = (
        os.O_RDONLY
        | getattr(os, "O_NOFOLLOW", 0)
        | getattr(os, "O_NONBLOCK", 0)
        | getattr(os, "O_BINARY", 0)
    )
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
            raise UnsafeFile(f"it is {info.st_size} bytes, over the limit of {limit} (not read)")
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


def parse_file(path: Path) -> dict[str, Any] | str:
    """The JSON object at ``path``, or why there is none (one line): read bounded
    (:func:`_read_bounded`), valid UTF-8 JSON with no key twice in one object
    (:func:`hnnbench._contracts.jsonio.loads`), an object, nested at most
    :data:`~hnnbench._record.codec.MAX_DEPTH` levels."""
    raw = _read_bounded(path, MAX_RECORD_BYTES)
    if isinstance(raw, UnsafeFile):
        return str(raw)
    try:
        data = jsonio.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        return "not valid JSON (not UTF-8 text)"
    except jsonio.DuplicateKeyError as err:
        return f"not valid JSON: {err}; write each key once"
    except RecursionError:
        return f"not a record: JSON nested deeper than {MAX_DEPTH} levels"
    except ValueError as err:
        return f"not valid JSON ({' '.join(str(err).split())[:200]})"
    if not isinstance(data, dict):
        return "not a JSON object"
    depth = depth_problems(data)
    return f"not a record: {depth[0]}" if depth else data


def read_record(path: Path) -> dict[str, Any] | None:
    """The record at ``path`` (decoded), or ``None`` if missing or unreadable (a job
    reads its own earlier record with it, on resume). Not checked: :func:`load` is
    what reads records for their results."""
    record = parse_file(path)
    if isinstance(record, str) or "status" not in record:
        return None
    return decode(record)


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
            raise UnsafeFile(
                f"its arrays would take {declared} bytes decompressed, over "
                f"the limit of {limit} (not read)"
            )
        for member in members:
            if not member.filename.endswith(".npy"):
                continue
            with zf.open(member) as raw:
                version = npy.read_magic(raw)
                if version not in ((1, 0), (2, 0)):
                    raise UnsafeFile(f"{member.filename}: .npy format {version} is not read")
                header = (
                    npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
                )
                shape, _, dtype = header(raw)
                if dtype.hasobject:
                    raise UnsafeFile(f"{member.filename} holds objects (not read)")
                size = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                if size > member.file_size:
                    raise UnsafeFile(
                        f"{member.filename} declares {size} bytes of data in "
                        f"a member of {member.file_size} (not read)"
                    )
            with zf.open(member) as raw:
                out[member.filename[:-4]] = npy.read_array(raw, allow_pickle=False)
    return out
