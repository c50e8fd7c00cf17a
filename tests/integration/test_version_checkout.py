"""The commit a record names, read from the checkout the tests run in (``git``; what an
install names: tests/unit/test_version.py)."""

from __future__ import annotations

import subprocess

from conftest import REPO

from hnnbench._record.environment import git_commit


def test_this_checkout_names_its_head():
    """This module is a tracked file of the clone the tests run in: its commit is the
    clone's HEAD (with ``-dirty`` for uncommitted changes)."""
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.strip()
    assert (git_commit() or "").split("-")[0] == head
