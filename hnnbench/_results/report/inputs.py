"""What a report is built from: the run records of one or more directories, and
where they came from."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hnnbench import _record as records
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._results import validity
from hnnbench._results.report.markdown import md_code, md_text

log = logging.getLogger("hnnbench")

__all__ = ["ReportError", "load_sweep", "load_sweeps", "provenance", "provenance_lines"]


class ReportError(HnnbenchError):
    """Directories that cannot be reported on."""


def load_sweeps(
    directories: Sequence[Path | str],
    *,
    strict: bool = False,
    refuse: bool | None = None,
    allow_unverified: bool = False,
) -> tuple[list[dict[str, Any]], list[records.Unreadable]]:
    """The records under every directory (several sweeps merge into one leaderboard),
    and the ``result.json`` files left out, unreadable or invalid (the caller names
    them): :func:`hnnbench._record.loader.load`, ``strict`` or not. ``refuse`` (default:
    ``strict``) makes any file left out a :class:`ReportError`, as does a directory
    that does not exist or holds no record. ``strict`` and refusing: the records must
    also pass the one strict validation of every door
    (:func:`hnnbench._results.validity.require_valid`; ``allow_unverified``: records
    whose plugins cannot be verified pass)."""
    if not directories:
        raise ReportError(
            "No sweep directory given: expected one or more directories holding result.json records"
        )
    for directory in map(Path, directories):
        if not directory.exists():
            raise ReportError(f"Sweep directory {directory} does not exist")
        if not directory.is_dir():
            raise ReportError(f"{directory} is not a directory (expected a sweep directory)")
    recs, bad = records.load(*directories, strict=strict)
    if bad and (strict if refuse is None else refuse):
        raise ReportError(f"{len(bad)} record(s) unreadable or invalid, e.g. {bad[0]}")
    if strict and (strict if refuse is None else refuse) and recs:
        validity.require_valid(recs, bad, door="strict load", allow_unverified=allow_unverified)
    if not recs:
        where = ", ".join(str(d) for d in directories)
        if bad:
            raise ReportError(
                f"No valid run records under {where}: {len(bad)} "
                f"{records.RECORD_NAME} left out, e.g. {bad[0]}; re-run those jobs "
                "(a sweep redoes them) or remove the files"
            )
        raise ReportError(
            f"No run records ({records.RECORD_NAME}) under {where}; run a sweep first, e.g. "
            "hnnbench -m system=spring model=all profile=quick"
        )
    return recs, bad


def load_sweep(
    *directories: Path | str, strict: bool = False, allow_unverified: bool = False
) -> list[dict[str, Any]]:
    """The records under the directories (see :func:`load_sweeps`); a warning names
    each file left out. What :func:`hnnbench.load` and :func:`hnnbench.sweep` read;
    ``strict``: every record must pass the strict validation (an error otherwise)."""
    recs, bad = load_sweeps(list(directories), strict=strict, allow_unverified=allow_unverified)
    for item in bad:
        log.warning("record left out: %s", item)
    return recs


def provenance(recs: Sequence[dict[str, Any]]) -> dict[str, list[str]]:
    """Where the records came from: distinct commands, git commits, machines, devices,
    hnnbench versions, dates and source directories, each sorted."""

    def distinct(values: Any) -> list[str]:
        return sorted({str(v) for v in values if v not in (None, "")})

    env = [r.get("environment") or {} for r in recs]
    commits = distinct(e.get("git_commit") for e in env)
    if commits and any(not e.get("git_commit") for e in env):
        commits.append("unknown")  # some records name none: not all from the named ones
    return {
        "command": distinct(r.get("command") for r in recs),
        "commit": commits,
        "machine": distinct(e.get("host") or e.get("platform") for e in env),
        "device": distinct(r.get("device") for r in recs),
        "hnnbench": distinct(e.get("hnnbench") for e in env),
        "date": distinct(str(r.get("created_at") or "")[:10] for r in recs),
        "source": distinct(r.get("source") for r in recs),
    }


def provenance_lines(prov: dict[str, list[str]], limit: int = 6) -> list[str]:
    """Markdown bullet lines for :func:`provenance` (long lists cut at ``limit``; every
    value escaped: :mod:`hnnbench._results.report.markdown`)."""

    def join(key: str, code: bool = True) -> str:
        vals = prov.get(key) or ["unknown"]
        shown = [md_code(v) if code else md_text(v) for v in vals[:limit]]
        more = f" and {len(vals) - limit} more" if len(vals) > limit else ""
        return ", ".join(shown) + more

    return [
        f"- Command: {join('command')}",
        f"- Git commit: {join('commit')}; hnnbench {join('hnnbench', code=False)}",
        f"- Machine: {join('machine', code=False)}; device {join('device', code=False)}; "
        f"run on {join('date', code=False)}",
    ]
