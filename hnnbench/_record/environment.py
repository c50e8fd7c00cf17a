"""The record's provenance: the versions of Python and the packages a job ran with,
the platform, the host, the git commit, and the time.
"""

from __future__ import annotations

import datetime as _dt
import platform
import subprocess
import sys
from collections.abc import Iterable
from functools import cache, lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = ["environment", "git_commit", "now_iso"]


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
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
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
    for dist in (
        "numpy",
        "scipy",
        "torch",
        "torchdiffeq",
        "safetensors",
        "jax",
        "jaxlib",
        "equinox",
        "optax",
        "diffrax",
        "rebound",
        "hydra-core",
        "omegaconf",
        *extra,
    ):
        env[dist] = _version(dist)
    return env


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
