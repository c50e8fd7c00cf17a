"""The version has one source, pyproject.toml: the installed metadata and
``hnnbench.__version__`` read it. The commit a record names: the checkout's, or the
one pip recorded for an install from a git URL."""

from __future__ import annotations

import json
from importlib import metadata

import pytest
import tomllib
from conftest import REPO

import hnnbench
from hnnbench._record.environment import installed_commit

SHA = "0123456789abcdef0123456789abcdef01234567"


def test_the_version_is_pyprojects():
    declared = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert hnnbench.__version__ == metadata.version("hnnbench") == declared


def _dist_with(tmp_path, name: str, direct_url: str | None):
    """A real installed distribution ``name`` (its dist-info on ``sys.path``) whose
    ``direct_url.json`` is ``direct_url`` (``None``: none written)."""
    info = tmp_path / f"{name.replace('-', '_')}-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    if direct_url is not None:
        (info / "direct_url.json").write_text(direct_url)
    return str(tmp_path)


@pytest.mark.parametrize(
    ("direct_url", "expected"),
    [
        (json.dumps({"url": "file:///r", "vcs_info": {"vcs": "git", "commit_id": SHA}}), SHA),
        ('{"url": "file:///src/repo", "dir_info": {}}', None),  # a directory: no commit
        ('{"url": "https://x/y.whl", "archive_info": {}}', None),
        (json.dumps({"url": "file:///r", "vcs_info": {"vcs": "hg", "commit_id": SHA}}), None),
        ('{"url": "file:///r", "vcs_info": {"vcs": "git", "commit_id": "HEAD; rm -rf"}}', None),
        ("not json", None),
        ("[]", None),
        (None, None),  # installed from an index
    ],
)
def test_an_install_names_the_commit_only_when_pip_recorded_one(
    tmp_path, monkeypatch, direct_url, expected
):
    monkeypatch.syspath_prepend(_dist_with(tmp_path, "commit-probe", direct_url))
    assert installed_commit("commit-probe") == expected
