"""Locating external data files: lookup order, SHA-256 checks, downloads, messages."""

from __future__ import annotations

import functools
import hashlib
import http.server
import logging
import os
import socket
import threading
from pathlib import Path

import pytest
from conftest import shared_data_dir

from hnnbench._contracts import data_files as data
from hnnbench._contracts.errors import DataError

FILENAME = "real_pend_h_1.txt"
SHA256 = "45d92988198b89a5933f5a53e67aa819d06937516f71a462ac09e1307d8b3411"
REPO = Path(__file__).resolve().parents[2]


SOURCE = shared_data_dir() / FILENAME
needs_data = pytest.mark.skipif(
    not SOURCE.is_file() and not os.environ.get("CI"),  # in CI, missing data fails
    reason=f"{FILENAME} not found (set HNNBENCH_DATA_DIR)",
)


@pytest.fixture(autouse=True)
def isolated(monkeypatch, tmp_path):
    """No data dir, and an empty cache under tmp_path (never the user's cache)."""
    monkeypatch.delenv(data.DATA_ENV, raising=False)
    monkeypatch.setenv(data.CACHE_ENV, str(tmp_path / "cache"))
    data._verified.clear()
    return tmp_path


def copy_to(directory: Path, content: bytes | None = None) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    dest = directory / FILENAME
    dest.write_bytes(SOURCE.read_bytes() if content is None else content)
    return dest


def test_cache_dir_follows_env(tmp_path):
    assert data.cache_dir() == tmp_path / "cache" / "data"


def test_missing_everywhere_gives_one_line_hint(monkeypatch, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv(data.DATA_ENV, str(empty))
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256=SHA256, explicit=None, url=None)
    msg = str(info.value)
    assert "\n" not in msg
    assert FILENAME in msg and "HNNBENCH_DATA_DIR" in msg
    assert str(data.cache_dir() / FILENAME) in msg  # exactly where to put it
    assert str(empty / FILENAME) in msg  # where it looked


def test_missing_without_env(tmp_path):
    with pytest.raises(DataError, match="HNNBENCH_DATA_DIR \\(not set\\)"):
        data.locate(FILENAME, sha256=SHA256)


@needs_data
def test_lookup_order(monkeypatch, tmp_path):
    explicit = copy_to(tmp_path / "explicit")
    env = copy_to(tmp_path / "env")
    cache = copy_to(data.cache_dir())
    monkeypatch.setenv(data.DATA_ENV, str(env.parent))
    # Explicit file, explicit directory, then env, then cache.
    assert data.locate(FILENAME, sha256=SHA256, explicit=str(explicit)) == explicit
    assert data.locate(FILENAME, sha256=SHA256, explicit=str(explicit.parent)) == explicit
    assert data.locate(FILENAME, sha256=SHA256, explicit=None) == env
    monkeypatch.delenv(data.DATA_ENV)
    assert data.locate(FILENAME, sha256=SHA256) == cache
    # An env dir without the file falls through to the cache.
    monkeypatch.setenv(data.DATA_ENV, str(tmp_path))
    assert data.locate(FILENAME, sha256=SHA256) == cache


@needs_data
def test_explicit_path_missing_is_an_error_not_a_fallback(monkeypatch, tmp_path):
    copy_to(data.cache_dir())
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256=SHA256, explicit=str(tmp_path / "nope.txt"))
    msg = str(info.value)
    assert "system.data_path" in msg and "nope.txt" in msg and "\n" not in msg


@needs_data
def test_shared_data_dir_verifies():
    assert data.locate(FILENAME, sha256=SHA256, explicit=str(SOURCE.parent)) == SOURCE
    assert data.sha256_file(SOURCE) == SHA256


@needs_data
@pytest.mark.parametrize("where", ["explicit", "env", "cache"])
def test_corrupt_copy_is_named(monkeypatch, tmp_path, where):
    good = SOURCE.read_bytes()
    directory = {"explicit": tmp_path / "x", "env": tmp_path / "env", "cache": data.cache_dir()}[
        where
    ]
    bad = copy_to(directory, good[: len(good) // 2])  # truncated
    if where == "env":
        monkeypatch.setenv(data.DATA_ENV, str(directory))
    explicit = str(bad) if where == "explicit" else None
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256=SHA256, explicit=explicit)
    msg = str(info.value)
    actual = hashlib.sha256(good[: len(good) // 2]).hexdigest()
    assert str(bad) in msg and "\n" not in msg
    assert SHA256[:12] in msg and actual[:12] in msg


@needs_data
def test_verification_is_memoised_and_sees_changes(tmp_path):
    path = copy_to(tmp_path / "x")
    data.verify(path, SHA256)
    assert data._verified  # cached
    path.write_bytes(b"changed")
    with pytest.raises(DataError, match="corrupt"):
        data.verify(path, SHA256)


@needs_data
def test_download_into_cache_atomically(tmp_path):
    url = SOURCE.as_uri()
    path = data.locate(FILENAME, sha256=SHA256, url=url)
    assert path == data.cache_dir() / FILENAME
    assert path.read_bytes() == SOURCE.read_bytes()
    assert [p.name for p in path.parent.iterdir()] == [FILENAME]  # no temp files left
    # Next time the cached copy is used without downloading.
    assert data.locate(FILENAME, sha256=SHA256, url="file:///nonexistent") == path


@needs_data
def test_download_with_wrong_hash_leaves_nothing(tmp_path):
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256="0" * 64, url=SOURCE.as_uri())
    assert "does not match" in str(info.value)
    assert list(data.cache_dir().iterdir()) == []


def test_download_failures_are_one_line_errors(tmp_path):
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256=SHA256, url=(tmp_path / "missing.txt").as_uri())
    assert "\n" not in str(info.value) and FILENAME in str(info.value)
    with pytest.raises(DataError, match="unsupported URL scheme"):
        data.locate(FILENAME, sha256=SHA256, url="ftp://example.invalid/x.txt")
    assert not any(data.cache_dir().glob("*.part"))


def test_download_times_out_instead_of_hanging(tmp_path):
    # A server that accepts connections (via the backlog) but never answers.
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        port = server.getsockname()[1]
        with pytest.raises(DataError) as info:
            data.locate(
                FILENAME, sha256=SHA256, url=f"http://127.0.0.1:{port}/x.txt", timeout_s=0.3
            )
    msg = str(info.value)
    assert "failed" in msg and "\n" not in msg
    assert not any(data.cache_dir().glob("*.part"))


# ------------------------------------------------------------------ downloads via pooch


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # no access log on stderr
        pass


@pytest.fixture
def http_server(tmp_path):
    """An HTTP server on 127.0.0.1 serving ``tmp_path / "www"``; yields its base URL."""
    root = tmp_path / "www"
    root.mkdir()
    handler = functools.partial(_QuietHandler, directory=str(root))
    with http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler) as server:
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield f"http://127.0.0.1:{server.server_address[1]}", root
        finally:
            server.shutdown()
            thread.join(timeout=10)


@needs_data
def test_download_over_http_with_pooch(http_server, caplog, capfd):
    base, root = http_server
    copy_to(root)
    with caplog.at_level(logging.INFO, logger="hnnbench"):
        path = data.locate(FILENAME, sha256=SHA256, url=f"{base}/{FILENAME}", timeout_s=10)
    assert path == data.cache_dir() / FILENAME
    assert path.read_bytes() == SOURCE.read_bytes()
    assert [p.name for p in path.parent.iterdir()] == [FILENAME]
    # pooch's "Downloading ..." line goes to the hnnbench logger, not to stderr.
    assert any(
        r.name == "hnnbench" and "Downloading" in r.getMessage() and base in r.getMessage()
        for r in caplog.records
    )
    assert "Downloading" not in capfd.readouterr().err
    # Remembered as verified (hashed while streaming), like a checked local file.
    assert data._verified and data.verify(path, SHA256) == path


def test_http_error_status_is_one_line(http_server):
    base, _ = http_server
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256=SHA256, url=f"{base}/absent.txt", timeout_s=10)
    msg = str(info.value)
    assert "404" in msg and "failed" in msg and "\n" not in msg
    assert list(data.cache_dir().iterdir()) == []


@needs_data
@pytest.mark.parametrize("scheme", ["file", "http"])
def test_download_larger_than_the_limit_is_abandoned(monkeypatch, http_server, scheme):
    base, root = http_server
    copy_to(root)
    monkeypatch.setattr(data, "MAX_DOWNLOAD_BYTES", 1000)
    url = SOURCE.as_uri() if scheme == "file" else f"{base}/{FILENAME}"
    with pytest.raises(DataError, match="larger than 1000 bytes") as info:
        data.locate(FILENAME, sha256=SHA256, url=url, timeout_s=10)
    assert "\n" not in str(info.value)
    assert list(data.cache_dir().iterdir()) == []  # pooch removed its temporary file


def test_unwritable_cache_is_one_line(monkeypatch, tmp_path):
    blocker = tmp_path / "file-not-dir"
    blocker.write_text("x")
    monkeypatch.setenv(data.CACHE_ENV, str(blocker))
    with pytest.raises(DataError) as info:
        data.locate(FILENAME, sha256=SHA256, url=(tmp_path / "x").as_uri())
    msg = str(info.value)
    assert "Cannot write to the cache directory" in msg and "HNNBENCH_CACHE_DIR" in msg
    assert "\n" not in msg
