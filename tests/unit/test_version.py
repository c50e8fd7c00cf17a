"""The version has one source, pyproject.toml: the installed metadata and
``hnnbench.__version__`` read it."""

from __future__ import annotations

from importlib import metadata

import tomllib
from conftest import REPO

import hnnbench


def test_the_version_is_pyprojects():
    declared = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert hnnbench.__version__ == metadata.version("hnnbench") == declared
