"""The one loader of records: every ``result.json`` below some directories, each file
that cannot be read or is not a record left out with a one-line reason
(docs/ARCHITECTURE.md, "The result record").
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hnnbench._contracts.names import one_line
from hnnbench._record.codec import decode
from hnnbench._record.fields import RECORD_NAME
from hnnbench._record.store import parse_file
from hnnbench._record.validation import (
    decoded_problems,
    schema_problems,
    shape_problems,
)

__all__ = ["Loaded", "Unreadable", "load", "load_records", "scan_records"]


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
    larger than :data:`~hnnbench._record.store.MAX_RECORD_BYTES`), is not a JSON object
    (or nests deeper than :data:`~hnnbench._record.codec.MAX_DEPTH`), or is not usable
    as a record (:func:`hnnbench._record.validation.shape_problems`: a required field
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
                record = (
                    f"invalid record: cannot be checked ({type(err).__name__}: "
                    f"{' '.join(str(err).split())[:200]})"
                )
            if isinstance(record, str):
                out.problems.append(Unreadable(path, record))
                continue
            record["path"] = str(path.parent)
            record["source"] = str(directory)
            out.records.append(record)
    return out


def _load_one(path: Path, strict: bool) -> dict[str, Any] | str:
    """The record at ``path`` (decoded), or why it is left out (one line)."""
    record = parse_file(path)
    if isinstance(record, str):
        return record
    problems = shape_problems(record)
    if not problems and strict:
        problems = schema_problems(record)  # the JSON as read: nothing to encode
    if not problems:
        record = decode(record)
        problems = decoded_problems(record) if strict else []
    if problems:
        return one_line(f"invalid record: {problems[0]}")
    return record


def scan_records(*directories: Path | str) -> tuple[list[dict[str, Any]], list[Unreadable]]:
    """``(records, problems)`` of :func:`load` (not strict)."""
    loaded = load(*directories)
    return loaded.records, loaded.problems


def load_records(*directories: Path | str) -> list[dict[str, Any]]:
    """The records of :func:`load` (not strict)."""
    return load(*directories).records
