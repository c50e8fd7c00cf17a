"""Locating external (measured) data files with a SHA-256 check (:func:`locate`): the
config's path, the data directories, the cache, a bounded download through pooch, the
member of a pinned archive (:class:`DataArchive`, downloaded once into the cache), in
that order, each file checked; a one-line :class:`~hnnbench.DataError` saying where it
looked (docs/DATA.md, "Where hnnbench looks"). Standard library only until used.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
import time
import urllib.parse
import urllib.request
import zipfile
import zlib
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Optional

from hnnbench._contracts import paths
from hnnbench._contracts.errors import DataError

__all__ = [
    "CACHE_ENV",
    "DATA_ENV",
    "DataArchive",
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


@dataclass(frozen=True)
class DataArchive:
    """A published archive (zip) that holds data files: where to fetch it and its
    SHA-256. :func:`locate` extracts the member it needs by file name.

    Attributes:
        url: ``http(s)://`` or ``file://`` URL of the archive.
        sha256: the archive's hex SHA-256 (each member is checked against its own, too).
        name: its file name in the cache (default: the URL's last path component).
    """

    url: str
    sha256: str
    name: str = ""

    @property
    def filename(self) -> str:
        """The archive's file name in the cache."""
        if self.name:
            return self.name
        tail = urllib.parse.urlsplit(self.url).path.rsplit("/", 1)[-1]
        return urllib.parse.unquote(tail) or "archive.zip"

    def cached(self) -> Path:
        """Where the archive is kept once fetched: ``<cache root>/data/archives/<name>``."""
        return cache_dir() / "archives" / self.filename


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
            path,
            sha256,
            actual,
            fix or f"Replace it with the original {path.name} (or delete it and fetch it again).",
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

    def __init__(self, dest: Path, timeout_s: float, fix: str = "") -> None:
        self.dest = dest
        self.timeout_s = timeout_s
        self.fix = fix
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
                + (
                    self.fix
                    or f"Copy the file to {self.dest} instead, or set {DATA_ENV} "
                    "to a directory holding it."
                )
            ) from None
        self.sha256 = sink.digest.hexdigest()


def download(url: str, dest: Path, *, sha256: str, timeout_s: float = 30.0, fix: str = "") -> Path:
    """Fetch ``url`` to ``dest`` with pooch, atomically, checking its SHA-256; raise
    DataError on any failure (bad URL, network error, timeout, too large, hash
    mismatch, unwritable cache).

    ``timeout_s`` bounds each network operation and the whole transfer; ``fix`` (what
    to do instead) replaces the messages' default advice.
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
    transfer = _Transfer(dest, timeout_s, fix)
    token = _in_download.set(True)
    try:
        pooch.retrieve(
            url,
            known_hash=f"sha256:{sha256.lower()}",
            fname=dest.name,
            path=dest.parent,
            downloader=transfer,
        )
    except DataError:
        raise
    except ValueError:  # pooch's hash check: the transfer itself raises only DataError
        actual = transfer.sha256 or "?"
        raise DataError(
            f"Downloaded {dest.name} from {url} does not match the expected file: its "
            f"SHA-256 is {actual[:12]}..., expected {sha256.lower()[:12]}.... "
            + (
                fix
                or "The mirror holds a different version; use another URL or copy the "
                f"original file to {dest}."
            )
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
    archive: Optional[DataArchive] = None,
) -> Path:
    """Find ``filename`` (explicit path, ``data_dir``, ``$HNNBENCH_DATA_DIR``, cache,
    download, then extraction from a downloaded archive), verify its SHA-256 and return
    its path. Raises a one-line DataError otherwise.

    Args:
        filename: the file's name, e.g. ``"real_pend_h_1.txt"``.
        sha256: its expected hex SHA-256.
        explicit: a path from the config: the file itself or a directory holding it.
        url: where to download it from when no local copy exists (``None``: no download).
        timeout_s: network timeout of the download.
        explicit_key, url_key: the config keys named in messages.
        archive: a published archive holding ``filename`` (``None``: none), fetched into
            the cache when no copy of the file exists (:func:`extract`).
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
        return verify(
            path, sha256, fix=f"Replace it with the original {filename} or fix {explicit_key}."
        )

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
        return verify(cache, sha256, fix=f"Delete it and copy the original {filename} to {cache}.")
    looked.append(f"the cache ({cache})")

    if url:
        return download(url, cache, sha256=sha256, timeout_s=timeout_s)
    if archive is not None:
        return from_archive(archive, filename, sha256=sha256, timeout_s=timeout_s)
    looked.append(f"no download URL ({url_key} is not set)")

    raise DataError(
        f"Data file {filename} not found; looked in: {', '.join(looked)}. "
        f"Set {DATA_ENV}=<directory holding {filename}>, or copy {filename} to {cache}, "
        f"or set {explicit_key}=<path to {filename}>."
    )


def from_archive(
    archive: DataArchive, filename: str, *, sha256: str, timeout_s: float = 30.0
) -> Path:
    """``<cache>/<filename>`` extracted from ``archive``: the archive from the cache
    (``archive.cached()``) or downloaded there (checked against ``archive.sha256``),
    then the member named ``filename`` checked against ``sha256``. Raises a one-line
    DataError that says what to fetch and from where when the archive cannot be had."""
    path = archive.cached()
    fetch = (
        f"Fetch {archive.url} (SHA-256 {archive.sha256.lower()}) and save it as "
        f"{path} (hnnbench extracts {filename} from it), or set {DATA_ENV}="
        f"<directory holding {filename}>."
    )
    if path.is_file():
        verify(path, archive.sha256, fix=f"Delete it to download it again. {fetch}")
    else:
        try:
            download(archive.url, path, sha256=archive.sha256, timeout_s=timeout_s, fix=fetch)
        except DataError as err:
            raise DataError(
                f"Data file {filename} is not on this machine and its archive "
                f"could not be fetched: {err}"
            ) from None
    return extract(path, filename, sha256=sha256, dest=cache_dir() / filename)


def extract(archive: Path, filename: str, *, sha256: str, dest: Path) -> Path:
    """Extract the member of the zip ``archive`` whose file name is ``filename`` (at any
    depth; the first whose SHA-256 is ``sha256`` where several are) to ``dest``,
    atomically, checked against ``sha256``; raise a one-line DataError otherwise."""
    try:
        with zipfile.ZipFile(archive) as zf:
            members = [
                m
                for m in zf.infolist()
                if not m.is_dir() and m.filename.replace("\\", "/").rsplit("/", 1)[-1] == filename
            ]
            if not members:
                raise DataError(
                    f"Archive {archive} holds no file named {filename}: it is "
                    "not the expected archive. Delete it to download it again."
                )
            found: list[str] = []
            for member in members:
                if member.file_size > MAX_DOWNLOAD_BYTES:
                    found.append(f"{member.filename} is larger than {MAX_DOWNLOAD_BYTES} bytes")
                    continue
                digest = _extract_member(zf, member, dest, sha256)
                if digest == sha256.lower():
                    _remember(dest, digest)
                    return dest
                found.append(f"{member.filename} has SHA-256 {digest[:12]}...")
    except (zipfile.BadZipFile, EOFError, NotImplementedError, RuntimeError, zlib.error) as exc:
        raise DataError(
            f"Archive {archive} is not a readable zip file ({_one_line(exc)}). "
            "Delete it to download it again."
        ) from None
    except OSError as exc:
        raise DataError(
            f"Cannot extract {filename} from {archive} into {dest.parent}: "
            f"{_one_line(exc.strerror or exc)}. Set {paths.CACHE_KEY}=<dir> or "
            f"{CACHE_ENV} to a writable directory."
        ) from None
    raise DataError(
        f"Archive {archive} holds no copy of {filename} with the expected "
        f"SHA-256 {sha256.lower()[:12]}... ({'; '.join(found)}). Delete it to "
        "download it again."
    )


def _extract_member(zf: zipfile.ZipFile, member: zipfile.ZipInfo, dest: Path, sha256: str) -> str:
    """Write ``member`` to a temporary file beside ``dest`` and move it into place if
    its SHA-256 is ``sha256`` (nothing is left behind otherwise); return its hex
    SHA-256."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    digest = hashlib.sha256()
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".part", dir=dest.parent)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as out, zf.open(member) as src:
            size = 0
            for block in iter(lambda: src.read(_CHUNK), b""):
                size += len(block)
                if size > MAX_DOWNLOAD_BYTES:  # the header's size may lie
                    return "larger than the limit"
                digest.update(block)
                out.write(block)
        if digest.hexdigest() == sha256.lower():
            os.replace(tmp, dest)
        return digest.hexdigest()
    finally:
        tmp.unlink(missing_ok=True)
