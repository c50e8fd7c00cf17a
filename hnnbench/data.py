"""Locating external (measured) data files, with a SHA-256 check.

:func:`locate` looks for a file in this order and returns the first hit:

1. an explicit path from the config (``system.data_path``): a file, or a directory that
   holds the file. If it is given but the file is not there, that is an error (no silent
   fallback to another copy);
2. ``$HNNBENCH_DATA_DIR/<filename>``;
3. the cache, ``<cache root>/data/<filename>``, where the cache root is
   ``$HNNBENCH_CACHE_DIR`` if set, else ``platformdirs.user_cache_dir("hnnbench")``;
4. a download from ``url`` (if one is configured) into the cache: streamed into a
   temporary file in the cache directory, hashed, then moved into place with
   :func:`os.replace`, so a partial download never looks like a cached file.

Every file found locally and every download is checked against the expected SHA-256.
A missing file, a failed download or a hash mismatch raises a one-line
:class:`hnnbench.errors.DataError` that says which file, where it looked and where to put
it. Successful checks are memoised per process, keyed by path, size and mtime.

This module imports only the standard library and platformdirs (no numpy, torch or JAX).
"""

from __future__ import annotations

import hashlib
import http.client
import os
import tempfile
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Optional

from hnnbench.errors import DataError

__all__ = [
    "CACHE_ENV",
    "DATA_ENV",
    "cache_dir",
    "download",
    "locate",
    "sha256_file",
    "verify",
]

#: Directory searched for data files before the cache.
DATA_ENV = "HNNBENCH_DATA_DIR"
#: Overrides the cache root (data files live under ``<root>/data``).
CACHE_ENV = "HNNBENCH_CACHE_DIR"
#: URL schemes :func:`download` accepts (``file`` is handy for local mirrors and tests).
URL_SCHEMES = ("https", "http", "file")
#: Downloads larger than this are abandoned (the files we know of are well below it).
MAX_DOWNLOAD_BYTES = 256 * 1024 * 1024

_CHUNK = 1 << 16
#: ``(resolved path, size, mtime_ns) -> sha256`` of files already hashed in this process.
_verified: dict[tuple[str, int, int], str] = {}


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _env_dir(name: str) -> Optional[Path]:
    value = os.environ.get(name, "").strip()
    return Path(value).expanduser() if value else None


def cache_dir() -> Path:
    """The directory holding cached data files (it need not exist yet)."""
    root = _env_dir(CACHE_ENV)
    if root is None:
        import platformdirs

        root = Path(platformdirs.user_cache_dir("hnnbench"))
    return root / "data"


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_CHUNK), b""):
            digest.update(block)
    return digest.hexdigest()


def _mismatch(path: Path, expected: str, actual: str, fix: str) -> DataError:
    return DataError(
        f"Data file {path} is corrupt or not the expected version: its SHA-256 is "
        f"{actual[:12]}..., expected {expected[:12]}.... {fix}"
    )


def verify(path: Path, sha256: str, *, fix: str = "") -> Path:
    """Check ``path`` against the expected hex SHA-256; return it, or raise DataError."""
    path = Path(path)
    try:
        stat = path.stat()
        key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
        if _verified.get(key) == sha256.lower():
            return path
        actual = sha256_file(path)
    except OSError as exc:
        raise DataError(
            f"Cannot read data file {path}: {_one_line(exc.strerror or exc)}. "
            "Check that it is a readable file."
        ) from None
    if actual != sha256.lower():
        raise _mismatch(
            path, sha256, actual,
            fix or f"Replace it with the original {path.name} (or delete it and fetch it "
            "again).",
        )
    _verified[key] = actual
    return path


def download(
    url: str, dest: Path, *, sha256: str, timeout_s: float = 30.0
) -> Path:
    """Fetch ``url`` to ``dest`` atomically, checking its SHA-256; raise DataError on any
    failure (bad URL, network error, timeout, too large, hash mismatch).

    ``timeout_s`` bounds each network operation and the whole transfer.
    """
    scheme = urllib.parse.urlsplit(url).scheme.lower()
    if scheme not in URL_SCHEMES:
        raise DataError(
            f"Cannot download {dest.name} from {url!r}: unsupported URL scheme "
            f"{scheme or '(none)'!r}; expected one of {', '.join(URL_SCHEMES)}."
        )
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".part",
                                        dir=dest.parent)
    except OSError as exc:
        raise DataError(
            f"Cannot write to the cache directory {dest.parent}: "
            f"{_one_line(exc.strerror or exc)}. Set {CACHE_ENV} to a writable directory."
        ) from None
    tmp = Path(tmp_name)
    digest = hashlib.sha256()
    deadline = time.monotonic() + timeout_s
    size = 0
    try:
        with os.fdopen(fd, "wb") as out:
            with urllib.request.urlopen(url, timeout=timeout_s) as response:
                while True:
                    block = response.read(_CHUNK)
                    if not block:
                        break
                    size += len(block)
                    if size > MAX_DOWNLOAD_BYTES:
                        raise DataError(
                            f"Download of {dest.name} from {url} was abandoned: larger "
                            f"than {MAX_DOWNLOAD_BYTES} bytes. Check the URL."
                        )
                    if time.monotonic() > deadline:
                        raise TimeoutError(f"transfer took longer than {timeout_s:g} s")
                    digest.update(block)
                    out.write(block)
        actual = digest.hexdigest()
        if actual != sha256.lower():
            raise DataError(
                f"Downloaded {dest.name} from {url} does not match the expected file: its "
                f"SHA-256 is {actual[:12]}..., expected {sha256.lower()[:12]}.... The "
                "mirror holds a different version; use another URL or copy the original "
                f"file to {dest}."
            )
        os.replace(tmp, dest)
    except DataError:
        raise
    except (OSError, ValueError, urllib.error.URLError, http.client.HTTPException) as exc:
        reason = getattr(exc, "reason", None) or exc
        raise DataError(
            f"Download of {dest.name} from {url} failed: {_one_line(reason)}. "
            f"Copy the file to {dest} instead, or set {DATA_ENV} to a directory holding it."
        ) from None
    finally:
        tmp.unlink(missing_ok=True)
    stat = dest.stat()
    _verified[(str(dest.resolve()), stat.st_size, stat.st_mtime_ns)] = actual
    return dest


def locate(
    filename: str,
    *,
    sha256: str,
    explicit: Optional[str] = None,
    url: Optional[str] = None,
    timeout_s: float = 30.0,
    explicit_key: str = "system.data_path",
    url_key: str = "system.url",
) -> Path:
    """Find ``filename`` (explicit path, ``$HNNBENCH_DATA_DIR``, cache, download), verify
    its SHA-256 and return its path. Raises a one-line DataError otherwise.

    Args:
        filename: the file's name, e.g. ``"real_pend_h_1.txt"``.
        sha256: its expected hex SHA-256.
        explicit: a path from the config: the file itself or a directory holding it.
        url: where to download it from when no local copy exists (``None``: no download).
        timeout_s: network timeout of the download.
        explicit_key, url_key: the config keys named in messages.
    """
    cache = cache_dir() / filename

    if explicit is not None and str(explicit).strip():
        given = Path(str(explicit).strip()).expanduser()
        path = given / filename if given.is_dir() else given
        if not path.is_file():
            raise DataError(
                f"{explicit_key}={explicit} does not point at {filename}: {path} does not "
                f"exist. Fix the path, or unset {explicit_key} to use {DATA_ENV} or the "
                f"cache ({cache})."
            )
        return verify(path, sha256, fix=f"Replace it with the original {filename} or fix "
                      f"{explicit_key}.")

    looked: list[str] = []
    data_dir = _env_dir(DATA_ENV)
    if data_dir is not None:
        path = data_dir / filename
        if path.is_file():
            return verify(path, sha256, fix=f"Replace it with the original {filename}.")
        looked.append(f"{DATA_ENV} ({path})")
    else:
        looked.append(f"{DATA_ENV} (not set)")

    if cache.is_file():
        return verify(cache, sha256, fix=f"Delete it and copy the original {filename} to "
                      f"{cache}.")
    looked.append(f"the cache ({cache})")

    if url:
        return download(url, cache, sha256=sha256, timeout_s=timeout_s)
    looked.append(f"no download URL ({url_key} is not set)")

    raise DataError(
        f"Data file {filename} not found; looked in: {', '.join(looked)}. "
        f"Set {DATA_ENV}=<directory holding {filename}>, or copy {filename} to {cache}, "
        f"or set {explicit_key}=<path to {filename}>."
    )
