"""On-disk cache of generated datasets and evaluation trajectories.

Entries are keyed by system name, version, the config fields that determine the data,
the seed and the kind (``dataset`` or ``evaluation``). Writes go to a unique temporary
file that is then renamed over the target (``os.replace``), so concurrent workers that
build the same entry never leave a torn file: the last complete write wins, and all
writes are identical. Each entry's SHA-256 is recorded beside it when it is written
(``<entry>.sha256``); an entry whose content no longer has that hash (altered, or
written without one) is rebuilt, never used.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Optional, TypeVar, Union

from hnnbench._contracts import paths
from hnnbench._contracts.plugin import Dataset, System, Trajectories
from hnnbench._record.store import atomic_path

log = logging.getLogger("hnnbench")

T = TypeVar("T", Dataset, Trajectories)

__all__ = ["cache_root", "cached", "entry_key", "file_sha256", "system_data"]

#: The layout of cached entries; part of every key, so a change of what a dataset holds
#: (2: systems that add input noise keep the clean inputs, ``Split.extras["x_clean"]``)
#: never serves an entry of the old layout.
CACHE_FORMAT = 2

#: Hex SHA-256 of a file (:func:`hnnbench._contracts.paths.sha256_file`).
file_sha256 = paths.sha256_file


def cache_root(explicit: Optional[Union[str, os.PathLike[str]]] = None) -> Path:
    """:func:`hnnbench._contracts.paths.cache_root`; a non-empty ``explicit`` acts as an override
    for this one call (kept for callers that pass a ``cache_dir`` setting)."""
    with paths.cache_root_override(explicit):
        return paths.cache_root()


def entry_key(system: System, seed: int, kind: str) -> str:
    """Stable hash of everything that determines the generated arrays."""
    payload = {
        "system": system.name,
        "class": f"{type(system).__module__}.{type(system).__qualname__}",
        "version": system.version,
        "data": system.cfg.data_fields(),
        "seed": int(seed),
        "kind": kind,
        "format": CACHE_FORMAT,
    }
    blob = json.dumps(payload, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:20]


def _hash_problem(path: Path, recorded: Path) -> Optional[str]:
    """Why the entry at ``path`` does not have the content hash recorded when it was
    written (``recorded``), or ``None``."""
    try:
        want = recorded.read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return "without its recorded content hash"
    if file_sha256(path) != want:
        return "not what was written (its content hash changed)"
    return None


def cached(
    system: System,
    seed: int,
    kind: str,
    build: Callable[[], T],
    loader: Callable[[Path], T],
    root: Optional[Path] = None,
) -> tuple[T, Path, bool]:
    """Load the entry from the cache, or ``build()`` and store it.

    ``root`` is the cache root (``None``: :func:`hnnbench._contracts.paths.cache_root`,
    which a job's ``cache_dir`` setting overrides); entries live under
    ``<root>/datasets/<system>``.

    Returns:
        ``(value, path, hit)``; ``hit`` is False when the entry was built now.
    """
    with paths.cache_root_override(root):
        directory = paths.dataset_cache_dir() / system.name
    path = directory / f"v{system.version}-seed{seed}-{kind}-{entry_key(system, seed, kind)}.npz"
    recorded = path.with_name(path.name + ".sha256")
    if path.exists():
        problem = _hash_problem(path, recorded)
        if problem is None:
            try:
                return loader(path), path, True
            except Exception as err:  # a corrupt entry is rebuilt, never fatal
                problem = f"unreadable ({err})"
        log.warning("cache entry %s is %s; rebuilding it", path, problem)
    log.info("generating %s %s (seed %d) ...", system.name, kind, seed)
    start = time.perf_counter()
    value = build()
    with atomic_path(path) as tmp:
        value.save(tmp)
    with atomic_path(recorded) as tmp:
        tmp.write_text(file_sha256(path) + "\n", encoding="ascii")
    log.info("  %s %s ready in %.1f s -> %s", system.name, kind, time.perf_counter() - start, path)
    # Return what a cache hit would load (same dtypes and memory layout), so a job's
    # metrics never depend on whether it or another worker built the entry.
    return loader(path), path, False


def system_data(
    system: System, seed: int, root: Optional[Path] = None
) -> tuple[tuple[Dataset, Path, bool], tuple[Trajectories, Path, bool]]:
    """The system's dataset and evaluation trajectories of ``seed`` (:func:`cached`
    each: read from the cache under ``root``, or built and stored there), as
    ``((data, path, hit), (trajectories, path, hit))``."""
    data = cached(
        system, seed, "dataset", functools.partial(system.dataset, seed), Dataset.load, root
    )
    traj = cached(
        system,
        seed,
        "evaluation",
        functools.partial(system.evaluation, seed),
        Trajectories.load,
        root,
    )
    return data, traj
