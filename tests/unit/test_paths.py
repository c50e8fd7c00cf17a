"""hnnbench._contracts.paths: the cache root and data directories (override > environment >
default), the overrides reaching every cache, and the one SHA-256 helper."""

from __future__ import annotations

import hashlib
import os
import threading
from pathlib import Path
from types import SimpleNamespace

import platformdirs
import pytest
from conftest import shared_data_dir

from hnnbench._contracts import data_files as data
from hnnbench._contracts import paths
from hnnbench._running import dataset_cache

FILENAME = "real_pend_h_1.txt"
SHA256 = "45d92988198b89a5933f5a53e67aa819d06937516f71a462ac09e1307d8b3411"
SOURCE = shared_data_dir() / FILENAME
needs_data = pytest.mark.skipif(
    not SOURCE.is_file() and not os.environ.get("CI"),  # in CI, missing data fails
    reason=f"{FILENAME} not found (set HNNBENCH_DATA_DIR)",
)


@pytest.fixture(autouse=True)
def clean_env(monkeypatch):
    monkeypatch.delenv(paths.CACHE_ENV, raising=False)
    monkeypatch.delenv(paths.DATA_ENV, raising=False)
    data._verified.clear()


# ------------------------------------------------------------------ precedence


def test_cache_root_precedence_override_env_platformdirs(monkeypatch, tmp_path):
    default = Path(platformdirs.user_cache_dir("hnnbench"))
    assert paths.cache_root() == default
    monkeypatch.setenv(paths.CACHE_ENV, str(tmp_path / "env"))
    assert paths.cache_root() == tmp_path / "env"
    with paths.cache_root_override(tmp_path / "job") as root:
        assert root == paths.cache_root() == tmp_path / "job"
        with paths.cache_root_override(str(tmp_path / "inner")):  # the innermost wins
            assert paths.cache_root() == tmp_path / "inner"
        assert paths.cache_root() == tmp_path / "job"
    assert paths.cache_root() == tmp_path / "env"  # gone with the block
    monkeypatch.setenv(paths.CACHE_ENV, "  ")  # blank: as if unset
    assert paths.cache_root() == default


def test_cache_layout_follows_the_root(tmp_path):
    with paths.cache_root_override(tmp_path):
        assert paths.dataset_cache_dir() == tmp_path / "datasets"
        assert paths.data_cache_dir() == data.cache_dir() == tmp_path / "data"
        assert paths.jax_compilation_cache_dir() == tmp_path / "jax-compilation"
        assert dataset_cache.cache_root() == tmp_path
        assert dataset_cache.cache_root(str(tmp_path / "x")) == tmp_path / "x"  # one call only
    assert dataset_cache.cache_root() == paths.cache_root()


def test_override_none_or_blank_changes_nothing(monkeypatch, tmp_path):
    monkeypatch.setenv(paths.CACHE_ENV, str(tmp_path / "env"))
    with paths.cache_root_override(tmp_path / "job"):
        for value in (None, "", "  "):
            with paths.overrides(cache_dir=value, data_dir=value):
                assert paths.cache_root() == tmp_path / "job"
                assert [name for name, _ in paths.data_dirs()] == [paths.DATA_ENV]


def test_override_is_made_absolute_and_expanded(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    with paths.cache_root_override("rel"):
        monkeypatch.chdir("/")  # a later chdir does not move it
        assert paths.cache_root() == tmp_path / "rel"
    with paths.cache_root_override("~/c"):
        assert paths.cache_root() == tmp_path / "home" / "c"


def test_data_dirs_override_then_env(monkeypatch, tmp_path):
    assert paths.data_dirs() == [(paths.DATA_ENV, None)]
    monkeypatch.setenv(paths.DATA_ENV, str(tmp_path / "env"))
    assert paths.data_dirs() == [(paths.DATA_ENV, tmp_path / "env")]
    with paths.data_dir_override(tmp_path / "cfg") as dirs:
        assert (
            dirs
            == paths.data_dirs()
            == [("data_dir", tmp_path / "cfg"), (paths.DATA_ENV, tmp_path / "env")]
        )
    assert paths.data_dirs() == [(paths.DATA_ENV, tmp_path / "env")]


def test_overrides_do_not_leak_between_threads(tmp_path):
    """Jobs run in threads of one process each see their own cache root."""
    seen: dict[str, Path] = {}
    barrier = threading.Barrier(2, timeout=10)

    def job(name: str) -> None:
        with paths.cache_root_override(tmp_path / name):
            barrier.wait()  # both overrides are active now
            seen[name] = data.cache_dir()
            barrier.wait()

    threads = [threading.Thread(target=job, args=(n,)) for n in ("a", "b")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=10)
    assert seen == {"a": tmp_path / "a" / "data", "b": tmp_path / "b" / "data"}


# ------------------------------------------------------------------ sha256


@pytest.mark.parametrize("size", [0, 1, (1 << 20) - 1, (1 << 20) + 17, 3 << 20])
def test_sha256_file_equals_hashlib(tmp_path, size):
    blob = os.urandom(size)
    path = tmp_path / "f.bin"
    path.write_bytes(blob)
    expected = hashlib.sha256(blob).hexdigest()
    assert paths.sha256_file(path) == paths.sha256_file(str(path)) == expected
    # One helper, whichever module a caller reaches it through.
    assert dataset_cache.file_sha256 is paths.sha256_file and data.sha256_file is paths.sha256_file


# ------------------------------------------------------------------ overrides reach caches


class _Blob:
    """A stand-in for a Dataset: bytes that save and load."""

    def __init__(self, payload: bytes) -> None:
        self.payload = payload

    def save(self, path: Path) -> None:
        Path(path).write_bytes(self.payload)

    @classmethod
    def load(cls, path: Path) -> _Blob:
        return cls(Path(path).read_bytes())


def test_override_reaches_dataset_cache(monkeypatch, tmp_path):
    monkeypatch.setenv(paths.CACHE_ENV, str(tmp_path / "env"))
    system = SimpleNamespace(name="fake", version=1, cfg=SimpleNamespace(data_fields=dict))
    with paths.cache_root_override(tmp_path / "job"):
        value, path, hit = dataset_cache.cached(
            system, 0, "dataset", lambda: _Blob(b"x"), _Blob.load
        )
    assert not hit and value.payload == b"x"
    assert path.parent == tmp_path / "job" / "datasets" / "fake"
    assert not (tmp_path / "env").exists()
    # An explicit root still wins over the ambient one (the concurrency test passes one).
    with paths.cache_root_override(tmp_path / "job"):
        _, path, hit = dataset_cache.cached(
            system, 0, "dataset", lambda: _Blob(b"y"), _Blob.load, tmp_path / "root"
        )
    assert not hit and path.parent == tmp_path / "root" / "datasets" / "fake"


@needs_data
def test_override_reaches_data_locate(monkeypatch, tmp_path):
    monkeypatch.setenv(paths.CACHE_ENV, str(tmp_path / "env"))
    with paths.overrides(cache_dir=tmp_path / "job"):
        path = data.locate(FILENAME, sha256=SHA256, url=SOURCE.as_uri())
        assert path == tmp_path / "job" / "data" / FILENAME  # downloaded into the job's cache
        assert data.locate(FILENAME, sha256=SHA256) == path  # and found there next time
    assert not (tmp_path / "env").exists()
    # data_dir is searched before HNNBENCH_DATA_DIR and the cache.
    monkeypatch.setenv(paths.DATA_ENV, str(tmp_path / "empty"))
    with paths.overrides(cache_dir=tmp_path / "job", data_dir=SOURCE.parent):
        assert data.locate(FILENAME, sha256=SHA256) == SOURCE


def test_data_dir_is_named_where_it_looked(tmp_path):
    with paths.overrides(cache_dir=tmp_path / "c", data_dir=tmp_path / "d"):
        with pytest.raises(data.DataError) as info:
            data.locate(FILENAME, sha256=SHA256)
    msg = str(info.value)
    assert f"data_dir ({tmp_path / 'd' / FILENAME})" in msg
    assert "HNNBENCH_DATA_DIR (not set)" in msg and str(tmp_path / "c" / "data") in msg


# ------------------------------------------------------------------ imports
