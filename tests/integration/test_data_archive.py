"""Measured data that arrives by itself: the data set's archive is downloaded into the
cache on first use and the member a system needs is extracted and checked (docs/DATA.md).

These machines cannot reach the published URL, so the archive here is a ``file://`` one
built from the member files in the shared data directory (the members keep their
published SHA-256, which is what hnnbench pins; the archive's own hash is then this
archive's, given as ``system.archive_sha256``)."""

from __future__ import annotations

import hashlib
import os
import re
import zipfile
from pathlib import Path

import pytest
from conftest import REPO, hnnbench, shared_data_dir

from hnnbench._contracts import data_files as data
from hnnbench._contracts.errors import DataError
from hnnbench_plugins.systems import real_double_pendulum as rdp
from hnnbench_plugins.systems import real_pendulum as rp

SHARED = shared_data_dir()
MEMBERS = (rp.FILENAME, rdp.FILENAME)
needs_data = pytest.mark.skipif(
    not all((SHARED / m).is_file() for m in MEMBERS) and not os.environ.get("CI"),
    reason="the Schmidt & Lipson files are not here (set HNNBENCH_DATA_DIR)",
)


@pytest.fixture(autouse=True)
def isolated(monkeypatch, tmp_path):
    """No data directory and an empty cache: only the archive can provide the files."""
    monkeypatch.delenv(data.DATA_ENV, raising=False)
    monkeypatch.setenv(data.CACHE_ENV, str(tmp_path / "cache"))
    data._verified.clear()


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def make_archive(path: Path, members: dict[str, bytes] | None = None) -> tuple[str, str]:
    """A zip at ``path`` holding the two measured files one folder deep (the matching is
    by file name) and a decoy; returns its ``file://`` URL and SHA-256."""
    if members is None:
        members = {f"invar_datasets/{m}": (SHARED / m).read_bytes() for m in MEMBERS}
        members["invar_datasets/notes/readme.txt"] = b"not a data file"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, content in members.items():
            zf.writestr(name, content)
    return path.as_uri(), sha256(path)


@needs_data
def test_first_use_downloads_the_archive_and_extracts_the_checked_member(tmp_path):
    url, digest = make_archive(tmp_path / "invar_datasets.zip")
    archive = data.DataArchive(url, digest)
    path = data.locate(rp.FILENAME, sha256=rp.SHA256, archive=archive)
    assert path == data.cache_dir() / rp.FILENAME
    assert sha256(path) == rp.SHA256 == sha256(SHARED / rp.FILENAME)
    assert archive.cached().is_file() and sha256(archive.cached()) == digest
    assert sorted(p.name for p in data.cache_dir().iterdir()) == ["archives", rp.FILENAME]
    # Offline afterwards: the source is gone, the file and the other member still come.
    (tmp_path / "invar_datasets.zip").unlink()
    data._verified.clear()
    assert data.locate(rp.FILENAME, sha256=rp.SHA256, archive=archive) == path
    other = data.locate(rdp.FILENAME, sha256=rdp.SHA256, archive=archive)
    assert other == data.cache_dir() / rdp.FILENAME and sha256(other) == rdp.SHA256


@needs_data
def test_the_systems_load_from_the_archive_and_local_copies_win(tmp_path, monkeypatch):
    url, digest = make_archive(tmp_path / "invar_datasets.zip")
    given = {"archive_url": url, "archive_sha256": digest}
    for cls in (rp.RealPendulum, rdp.RealDoublePendulum):
        path, table = cls(cls.Config(**given)).load()
        assert path == data.cache_dir() / cls.data_file and len(table) > 500
    # An explicit path and $HNNBENCH_DATA_DIR come first: no archive is needed.
    missing = {"archive_url": (tmp_path / "absent.zip").as_uri(), "archive_sha256": digest}
    explicit = rp.RealPendulum(rp.RealPendulumConfig(data_path=str(SHARED), **missing))
    assert explicit.load()[0] == SHARED / rp.FILENAME
    monkeypatch.setenv(data.DATA_ENV, str(SHARED))
    assert rp.RealPendulum(rp.RealPendulumConfig(**missing)).load()[0] == SHARED / rp.FILENAME


@needs_data
def test_an_archive_of_another_hash_or_member_is_refused(tmp_path):
    url, digest = make_archive(tmp_path / "invar_datasets.zip")
    with pytest.raises(DataError, match="does not match") as info:
        data.locate(rp.FILENAME, sha256=rp.SHA256, archive=data.DataArchive(url, "0" * 64))
    assert "\n" not in str(info.value) and url in str(info.value)
    assert not (data.cache_dir() / rp.FILENAME).exists()
    assert not any(data.cache_dir().rglob("*.zip"))  # nothing half-fetched kept
    # The archive is the expected one, but its member is not the published file.
    bad = tmp_path / "bad.zip"
    url, digest = make_archive(bad, {f"x/{rp.FILENAME}": b"%o v\r\n1 0 0 0\r\n"})
    with pytest.raises(DataError, match="no copy of real_pend_h_1.txt with the expected"):
        data.locate(rp.FILENAME, sha256=rp.SHA256, archive=data.DataArchive(url, digest))
    assert not (data.cache_dir() / rp.FILENAME).exists()
    assert [p.name for p in data.cache_dir().iterdir()] == ["archives"]  # no temp file


def test_offline_without_a_copy_says_what_to_fetch_and_from_where(tmp_path):
    archive = data.DataArchive(
        (tmp_path / "offline" / "invar_datasets.zip").as_uri(), rp.ARCHIVE_SHA256
    )
    with pytest.raises(DataError) as info:
        data.locate(rp.FILENAME, sha256=rp.SHA256, archive=archive)
    message = str(info.value)
    assert "\n" not in message
    assert f"Fetch {archive.url} (SHA-256 {rp.ARCHIVE_SHA256})" in message
    assert str(archive.cached()) in message and "HNNBENCH_DATA_DIR" in message


def test_the_defaults_are_the_published_archive_outside_the_dataset_key():
    cfg = rp.RealPendulumConfig()
    assert cfg.archive_url == rp.ARCHIVE_URL and cfg.archive_url.startswith("https://")
    assert cfg.archive_url.endswith("/experiment-real/invar_datasets.zip")
    assert "Physics-aware-AI/Symplectic-ODENet" in cfg.archive_url
    assert {"archive_url", "archive_sha256"}.isdisjoint(cfg.data_fields())
    assert rdp.RealDoublePendulumConfig().archive_sha256 == rp.ARCHIVE_SHA256
    readme = SHARED / "README.md"
    if readme.is_file():  # the data set's own note names the archive's hash
        named = re.findall(
            r"invar_datasets\.zip`?\s*\(SHA-256 ([0-9a-f]{64})\)", readme.read_text()
        )
        assert named == [rp.ARCHIVE_SHA256]
    with pytest.raises(Exception, match="archive_sha256"):
        rp.RealPendulumConfig(archive_sha256="abc").validate()
    with pytest.raises(Exception, match="archive_url"):
        rp.RealPendulumConfig(archive_url="ftp://x/y.zip").validate()


@needs_data
@pytest.mark.slow
def test_a_sweep_of_the_measured_systems_needs_no_manual_step(tmp_path):
    """The command line alone, no HNNBENCH_DATA_DIR, an empty cache: the archive comes
    (here from a file:// URL) and both measured systems run."""
    url, digest = make_archive(tmp_path / "invar_datasets.zip")
    env = {**os.environ, "HNNBENCH_DATA_DIR": "", "HNNBENCH_CACHE_DIR": str(tmp_path / "c")}
    proc = hnnbench(
        "-m",
        "system=real_pendulum,real_double_pendulum",
        "model=standing_still",
        "profile=quick",
        f"system.archive_url={url}",
        f"system.archive_sha256={digest}",
        f"hydra.sweep.dir={tmp_path / 'sweep'}",
        cwd=REPO,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    for member in MEMBERS:
        assert sha256(tmp_path / "c" / "data" / member) == sha256(SHARED / member)
    assert len(list((tmp_path / "sweep").rglob("result.json"))) == 2
