"""Locating external (measured) data files with a SHA-256 check (:func:`locate`): the
config's path, the data directories, the cache, a bounded download through pooch, in
that order, each file checked; a one-line :class:`~hnnbench.DataError` saying where it
looked (docs/DATA.md, "Where hnnbench looks"). Standard library only until used.
"""

from __future__ import annotations

import hashlib
import logging
import time
import urllib.parse
import urllib.request
from contextvars import ContextVar
from pathlib import Path
from typing import Any, BinaryIO, Optional

from hnnbench._contracts import paths
from hnnbench._contracts.errors import DataError

__all__ = [
    "CACHE_ENV",
    "DATA_ENV",
    "cache_dir",
    "download",
    "locate",
    "sha256_file",
    "verify",
]

log = logging.getLogger("hnnbench")

#: Directory searched for data files before the cache (after a job's ``data_dir``).
DATA_ENV = paths.DATA_ENV
#: Overrides the cache root (data files live under ``<root>/data``).
CACHE_ENV = paths.CACHE_ENV
#: URL schemes :func:`download` accepts (``file`` is handy for local mirrors and tests).
URL_SCHEMES = ("https", "http", "file")
#: Downloads larger than this are abandoned (the files we know of are well below it).
MAX_DOWNLOAD_BYTES = 256 * 1024 * 1024

_CHUNK = 1 << 16
#: ``(resolved path, size, mtime_ns) -> sha256`` of files already hashed in this process.
_verified: dict[tuple[str, int, int], str] = {}

#: Hex SHA-256 of a file's bytes (:func:`hnnbench._contracts.paths.sha256_file`).
sha256_file = paths.sha256_file


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def cache_dir() -> Path:
    """The directory holding cached data files (it need not exist yet)."""
    return paths.data_cache_dir()


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


def _remember(path: Path, sha256: str) -> None:
    stat = path.stat()
    _verified[(str(path.resolve()), stat.st_size, stat.st_mtime_ns)] = sha256.lower()


# ----------------------------------------------------------------------------- pooch

#: True while :func:`download` runs pooch in this context: pooch's log lines are then
#: re-emitted on the ``hnnbench`` logger instead of pooch's own stderr handler.
_in_download: ContextVar[bool] = ContextVar("hnnbench_in_download", default=False)


class _ToHnnbenchLog(logging.Filter):
    """A filter on pooch's logger that moves the records of our downloads to ours."""

    def filter(self, record: logging.LogRecord) -> bool:
        if not _in_download.get():
            return True  # someone else's use of pooch: leave it alone
        log.log(record.levelno, "%s", _one_line(record.getMessage()))
        return False


_LOG_FILTER = _ToHnnbenchLog()


def _pooch() -> Any:
    """pooch, imported on first use (it costs about 0.1 s), with our log filter."""
    import pooch

    pooch.get_logger().addFilter(_LOG_FILTER)  # a no-op once added
    return pooch


class _Sink:
    """A write-only file wrapper that hashes what passes and enforces the size limit
    and the deadline of one transfer."""

    def __init__(self, out: BinaryIO, name: str, url: str, timeout_s: float) -> None:
        self.out, self.name, self.url, self.timeout_s = out, name, url, timeout_s
        self.digest = hashlib.sha256()
        self.size = 0
        self.limit = MAX_DOWNLOAD_BYTES
        self.deadline = time.monotonic() + timeout_s

    def write(self, block: bytes) -> int:
        self.size += len(block)
        if self.size > self.limit:
            raise DataError(
                f"Download of {self.name} from {self.url} was abandoned: larger than "
                f"{self.limit} bytes. Check the URL."
            )
        if time.monotonic() > self.deadline:
            raise TimeoutError(f"transfer took longer than {self.timeout_s:g} s")
        self.digest.update(block)
        return self.out.write(block)

    def flush(self) -> None:
        self.out.flush()


class _Transfer:
    """The downloader handed to :func:`pooch.retrieve`: fetches ``url`` into the
    temporary file pooch names, through a :class:`_Sink`. ``http(s)`` goes through
    :class:`pooch.HTTPDownloader` (requests); ``file`` URLs, which pooch does not handle,
    are read with :func:`urllib.request.urlopen`. Every failure becomes a one-line
    DataError (pooch then deletes the temporary file); :attr:`sha256` is the digest of
    what was fetched, for the message when pooch finds that it does not match."""

    def __init__(self, dest: Path, timeout_s: float) -> None:
        self.dest = dest
        self.timeout_s = timeout_s
        self.sha256: Optional[str] = None

    def __call__(self, url: str, output_file: Any, pooch: Any, check_only: bool = False) -> None:
        scheme = urllib.parse.urlsplit(url).scheme.lower()
        try:
            with open(output_file, "wb") as out:
                sink = _Sink(out, self.dest.name, url, self.timeout_s)
                if scheme == "file":
                    with urllib.request.urlopen(url, timeout=self.timeout_s) as src:
                        for block in iter(lambda: src.read(_CHUNK), b""):
                            sink.write(block)
                else:
                    _pooch().HTTPDownloader(timeout=self.timeout_s, chunk_size=_CHUNK)(
                        url, sink, pooch
                    )
        except DataError:
            raise
        except (OSError, ValueError) as exc:  # requests' errors are OSErrors too
            reason = getattr(exc, "reason", None) or exc
            raise DataError(
                f"Download of {self.dest.name} from {url} failed: {_one_line(reason)}. "
                f"Copy the file to {self.dest} instead, or set {DATA_ENV} to a directory "
                "holding it."
            ) from None
        self.sha256 = sink.digest.hexdigest()


def download(
    url: str, dest: Path, *, sha256: str, timeout_s: float = 30.0
) -> Path:
    """Fetch ``url`` to ``dest`` with pooch, atomically, checking its SHA-256; raise
    DataError on any failure (bad URL, network error, timeout, too large, hash
    mismatch, unwritable cache).

    ``timeout_s`` bounds each network operation and the whole transfer.
    """
    dest = Path(dest)
    scheme = urllib.parse.urlsplit(url).scheme.lower()
    if scheme not in URL_SCHEMES:
        raise DataError(
            f"Cannot download {dest.name} from {url!r}: unsupported URL scheme "
            f"{scheme or '(none)'!r}; expected one of {', '.join(URL_SCHEMES)}."
        )

    def unwritable(exc: OSError) -> DataError:
        return DataError(
            f"Cannot write to the cache directory {dest.parent}: "
            f"{_one_line(exc.strerror or exc)}. Set {paths.CACHE_KEY}=<dir> or {CACHE_ENV} "
            "to a writable directory."
        )

    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise unwritable(exc) from None
    pooch = _pooch()
    transfer = _Transfer(dest, timeout_s)
    token = _in_download.set(True)
    try:
        pooch.retrieve(url, known_hash=f"sha256:{sha256.lower()}", fname=dest.name,
                       path=dest.parent, downloader=transfer)
    except DataError:
        raise
    except ValueError:  # pooch's hash check: the transfer itself raises only DataError
        actual = transfer.sha256 or "?"
        raise DataError(
            f"Downloaded {dest.name} from {url} does not match the expected file: its "
            f"SHA-256 is {actual[:12]}..., expected {sha256.lower()[:12]}.... The "
            "mirror holds a different version; use another URL or copy the original "
            f"file to {dest}."
        ) from None
    except OSError as exc:  # pooch's temporary file or the move into place
        raise unwritable(exc) from None
    finally:
        _in_download.reset(token)
    if transfer.sha256 is None:  # pooch found a matching copy that another process put
        return verify(dest, sha256)
    _remember(dest, transfer.sha256)
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
    """Find ``filename`` (explicit path, ``data_dir``, ``$HNNBENCH_DATA_DIR``, cache,
    download), verify its SHA-256 and return its path. Raises a one-line DataError
    otherwise.

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
    for name, directory in paths.data_dirs():
        if directory is None:
            looked.append(f"{name} (not set)")
            continue
        path = directory / filename
        if path.is_file():
            return verify(path, sha256, fix=f"Replace it with the original {filename}.")
        looked.append(f"{name} ({path})")

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
