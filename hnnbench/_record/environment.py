"""The record's provenance: the versions of Python and the packages a job ran with,
the platform, the host, the git commit, and the time.
"""

from __future__ import annotations

import datetime as _dt
import json
import platform
import re
import subprocess
import sys
from collections.abc import Iterable
from functools import cache, lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = ["blas_kernel", "environment", "git_commit", "now_iso", "numpy_simd"]


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
    """The commit of the hnnbench source: its git checkout's ``HEAD`` (``-dirty`` with
    uncommitted changes) when this module is a tracked file of one (a clone, an editable
    install), else the commit an install from a git URL was built from
    (:func:`installed_commit`); ``None`` for any other install."""
    here = Path(__file__).resolve().parent
    try:
        tracked = subprocess.run(
            ["git", "ls-files", "--error-unmatch", Path(__file__).name],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
        )
        # Not tracked: an installed copy, perhaps inside some other checkout (a venv in
        # a clone), whose HEAD says nothing of this code.
        if tracked.returncode != 0:
            return installed_commit()
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5
        )
        if out.returncode != 0:
            return installed_commit()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):  # no git, or a slow one
        return installed_commit()
    return out.stdout.strip() + ("-dirty" if dirty else "")


def installed_commit(dist: str = "hnnbench") -> str | None:
    """The git commit an install of ``dist`` was built from, as pip records it for an
    install from a git URL (``pip install "hnnbench @ git+file:///path@<commit>"``;
    ``vcs_info.commit_id`` of PEP 610's ``direct_url.json``); ``None`` for an install
    from a directory, an index or a wheel, which name no commit."""
    try:
        text = metadata.distribution(dist).read_text("direct_url.json")
        info = json.loads(text) if text else None
    except (metadata.PackageNotFoundError, ValueError):
        return None
    vcs = info.get("vcs_info") if isinstance(info, dict) else None
    if not isinstance(vcs, dict) or vcs.get("vcs") != "git":
        return None
    commit = vcs.get("commit_id")
    return commit if isinstance(commit, str) and re.fullmatch(r"[0-9a-f]{40}", commit) else None


@cache
def blas_kernel() -> str | None:
    """The OpenBLAS kernel numpy's and scipy's BLAS chose for this CPU (e.g.
    ``"Haswell"``, ``"SkylakeX"``; several joined by ``","``), ``None`` without OpenBLAS.

    Data generation integrates with BLAS, and the kernel sets the last bits of float64
    results: the same config and seed give byte-different data files (and so other
    ``data.*_sha256``) on CPUs that pick another kernel. ``OPENBLAS_CORETYPE=<kernel>``
    forces one (:mod:`hnnbench._running.data_hashes`, for ``hnnbench check --rerun``)."""
    import numpy  # noqa: F401  (their BLAS libraries are loaded by importing them)
    import scipy.linalg  # noqa: F401
    import threadpoolctl

    kernels = {
        str(lib["architecture"])
        for lib in threadpoolctl.threadpool_info()
        if lib.get("internal_api") == "openblas" and lib.get("architecture")
    }
    return ",".join(sorted(kernels)) or None


@cache
def numpy_simd() -> str | None:
    """The SIMD targets numpy dispatches to on this CPU beyond its baseline, e.g.
    ``"X86_V3,X86_V4,AVX512_ICL,AVX512_SPR"`` (``""``: the baseline only; ``None``:
    this numpy does not say). Its vectorised ``sin``, ``exp``, ... differ in their last
    bits between targets, as BLAS kernels do; ``NPY_DISABLE_CPU_FEATURES`` turns targets
    off."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:
        return None
    return ",".join(t for t in __cpu_dispatch__ if __cpu_features__.get(t))


def environment(extra: Iterable[str] = ()) -> dict[str, Any]:
    """Versions and platform, for reproducing a record."""
    env: dict[str, Any] = {
        "hnnbench": _version("hnnbench"),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "machine": platform.machine(),
        "host": platform.node(),
        "git_commit": git_commit(),
        "blas_kernel": blas_kernel(),
        "numpy_simd": numpy_simd(),
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
