"""Where hnnbench keeps its files: the cache root (:func:`cache_root`), the data
directories (:func:`data_dirs`), their per-job overrides (context variables), a file's
SHA-256, and :func:`safe_join` (every path built from a record's or plugin's name: one
plain component, inside its root; docs/DATA.md, "One cache root for everything").
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from collections.abc import Iterator
from contextvars import ContextVar
from pathlib import Path
from typing import Optional, Union

from hnnbench._contracts.errors import UnsafePathError

__all__ = [
    "APP_NAME",
    "CACHE_ENV",
    "DATA_ENV",
    "cache_root",
    "cache_root_override",
    "data_cache_dir",
    "data_dir_override",
    "data_dirs",
    "dataset_cache_dir",
    "jax_compilation_cache_dir",
    "overrides",
    "safe_join",
    "sha256_file",
]

#: Name of the user cache directory (``platformdirs.user_cache_dir(APP_NAME)``).
APP_NAME = "hnnbench"
#: Environment variable naming the cache root.
CACHE_ENV = "HNNBENCH_CACHE_DIR"
#: Environment variable naming a directory of measured data files.
DATA_ENV = "HNNBENCH_DATA_DIR"
#: Config key of the cache-root override (named in messages).
CACHE_KEY = "cache_dir"
#: Config key of the data-directory override (named in messages).
DATA_KEY = "data_dir"

PathLike = Union[str, "os.PathLike[str]"]

_cache_override: ContextVar[Optional[Path]] = ContextVar("hnnbench_cache_root", default=None)
_data_override: ContextVar[Optional[Path]] = ContextVar("hnnbench_data_dir", default=None)

_CHUNK = 1 << 20


def _given(value: Optional[PathLike]) -> Optional[Path]:
    """``value`` as an absolute path, or None when it is None or blank."""
    if value is None:
        return None
    text = os.fspath(value).strip()
    return Path(text).expanduser().absolute() if text else None


def _env(name: str) -> Optional[Path]:
    value = os.environ.get(name, "").strip()
    return Path(value).expanduser() if value else None


def cache_root() -> Path:
    """The cache root (it need not exist): the active :func:`cache_root_override`, else
    ``$HNNBENCH_CACHE_DIR``, else the user cache dir."""
    override = _cache_override.get()
    if override is not None:
        return override
    env = _env(CACHE_ENV)
    if env is not None:
        return env
    import platformdirs

    return Path(platformdirs.user_cache_dir(APP_NAME))


def dataset_cache_dir() -> Path:
    """Where generated datasets and evaluation trajectories are cached."""
    return cache_root() / "datasets"


def data_cache_dir() -> Path:
    """Where measured data files are cached (and downloaded to)."""
    return cache_root() / "data"


def jax_compilation_cache_dir() -> Path:
    """Where JAX's persistent compilation cache goes (unless JAX is told otherwise)."""
    return cache_root() / "jax-compilation"


def data_dirs() -> list[tuple[str, Optional[Path]]]:
    """The directories searched for measured data files before the cache, in order, as
    ``(name, directory)``: ``("data_dir", <dir>)`` while a :func:`data_dir_override` is
    active, then always ``("HNNBENCH_DATA_DIR", <dir or None when unset>)``."""
    found: list[tuple[str, Optional[Path]]] = []
    override = _data_override.get()
    if override is not None:
        found.append((DATA_KEY, override))
    found.append((DATA_ENV, _env(DATA_ENV)))
    return found


@contextlib.contextmanager
def _override(var: ContextVar[Optional[Path]], value: Optional[PathLike]) -> Iterator[None]:
    path = _given(value)
    if path is None:  # nothing given: whatever applied outside applies inside too
        yield
        return
    token = var.set(path)
    try:
        yield
    finally:
        var.reset(token)


@contextlib.contextmanager
def cache_root_override(path: Optional[PathLike]) -> Iterator[Path]:
    """Make :func:`cache_root` return ``path`` (made absolute now) inside the block.

    ``None`` or a blank string changes nothing, so a job can pass its ``cache_dir``
    setting as it is. Overrides nest; the innermost one wins.
    """
    with _override(_cache_override, path):
        yield cache_root()


@contextlib.contextmanager
def data_dir_override(path: Optional[PathLike]) -> Iterator[list[tuple[str, Optional[Path]]]]:
    """Search ``path`` (made absolute now) for measured data files before
    ``$HNNBENCH_DATA_DIR`` inside the block (see :func:`data_dirs`). ``None`` or a blank
    string changes nothing. Overrides nest; the innermost one wins."""
    with _override(_data_override, path):
        yield data_dirs()


@contextlib.contextmanager
def overrides(
    cache_dir: Optional[PathLike] = None, data_dir: Optional[PathLike] = None
) -> Iterator[None]:
    """Both overrides at once: what a job enters with its ``cache_dir`` and ``data_dir``
    settings (``None``: that one is not overridden)."""
    with cache_root_override(cache_dir), data_dir_override(data_dir):
        yield


def sha256_file(path: PathLike) -> str:
    """Hex SHA-256 of a file's bytes (read in 1 MiB blocks)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_CHUNK), b""):
            digest.update(block)
    return digest.hexdigest()


#: Characters a path component built from a name may never hold: separators (both
#: platforms'), NUL, and line breaks.
_UNSAFE_CHARS = frozenset("/\\\0\n\r")


def safe_join(root: PathLike, *names: str) -> Path:
    """``root / name / ...``, where each name must be one plain file-name component (a
    non-empty string, not ``.`` or ``..``, with no separator, NUL or line break) and the
    result, symbolic links resolved, must lie inside ``root`` (resolved). The one way a
    path is built from a name that a record or a plugin supplies.

    Raises:
        UnsafePathError: a name that is not a plain component, or a path that would lead
            outside ``root`` (naming both).
    """
    base = Path(root)
    for name in names:
        if (
            not isinstance(name, str)
            or name in ("", ".", "..")
            or any(c in _UNSAFE_CHARS for c in name)
            or os.path.isabs(name)
        ):
            raise UnsafePathError(
                f"refusing the path component {name!r} under {base}: "
                "a name must be one plain file-name component"
            )
    path = base.joinpath(*names)
    inside, target = base.resolve(), path.resolve()
    if target != inside and inside not in target.parents:
        raise UnsafePathError(f"refusing {path}: it resolves to {target}, outside {inside}")
    return path
