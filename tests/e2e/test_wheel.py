"""conf/ ships inside the package: a built wheel, installed non-editable, finds it from
any working directory. What commit an install's records name."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from conftest import REPO

pytestmark = pytest.mark.slow


def test_wheel_install_finds_config_from_any_directory(tmp_path):
    dist, site, elsewhere = tmp_path / "dist", tmp_path / "site", tmp_path / "elsewhere"
    elsewhere.mkdir()
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "-w",
            str(dist),
            str(REPO),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    (wheel,) = dist.glob("hnnbench-*.whl")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--target",
            str(site),
            str(wheel),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    assert (site / "hnnbench_conf" / "config.yaml").exists()
    assert (site / "hnnbench_plugins" / "systems" / "spring.py").exists()
    env = {**os.environ, "PYTHONPATH": str(site)}
    code = (
        "import sys, hnnbench; print(hnnbench.__file__); "
        "from hnnbench._entry.command import run; "
        "sys.exit(run(['--cfg', 'job', 'system=pendulum', 'model=oracle']))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=elsewhere, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0].startswith(str(site))
    assert "name: pendulum" in proc.stdout and "radius_min: 1.3" in proc.stdout
    code = (
        "import sys; from hnnbench._entry.command import run; sys.exit(run(["
        "'system=spring', 'model=oracle', 'profile=quick', 'hydra.run.dir=out']))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=elsewhere, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (elsewhere / "out" / "result.json").exists()
    # A wheel names no commit: nothing says which one it was built from.
    record = json.loads((elsewhere / "out" / "result.json").read_text())
    assert record["environment"]["git_commit"] is None


def test_an_install_from_a_git_url_records_its_commit(tmp_path):
    """``pip install "hnnbench @ git+file://<clone>@<commit>"`` (a pinned install for a
    long sweep, docs/LEADERBOARD.md): the records of that install name the commit, read
    from pip's ``direct_url.json``, wherever it runs."""
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.strip()
    site, elsewhere = tmp_path / "site", tmp_path / "elsewhere"
    elsewhere.mkdir()
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "--target",
            str(site),
            f"hnnbench @ git+file://{REPO}@{head}",
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    env = {**os.environ, "PYTHONPATH": str(site)}
    code = (
        "import hnnbench; from hnnbench._record.environment import git_commit; "
        "print(hnnbench.__file__); print(git_commit())"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=elsewhere, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    where, commit = proc.stdout.split()
    assert where.startswith(str(site)) and commit == head, proc.stdout
