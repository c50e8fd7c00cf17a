"""conf/ ships inside the package: a built wheel, installed non-editable, finds it from
any working directory. What commit an install's records name."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from conftest import REPO, pip_install

pytestmark = pytest.mark.slow


def _python_in(site, cwd, code: str) -> subprocess.CompletedProcess[str]:
    """``python -c code`` in ``cwd`` with only ``site``'s hnnbench installed ahead of the
    environment's; it must exit 0."""
    env = {**os.environ, "PYTHONPATH": str(site)}
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc


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
    pip_install(site, str(wheel))
    assert (site / "hnnbench_conf" / "config.yaml").exists()
    assert (site / "hnnbench_plugins" / "systems" / "spring.py").exists()
    (info,) = site.glob("hnnbench-*.dist-info")  # the licence travels with the wheel
    assert "License-Expression: Apache-2.0" in (info / "METADATA").read_text()
    assert (info / "licenses" / "LICENSE").read_text() == (REPO / "LICENSE").read_text()
    proc = _python_in(
        site,
        elsewhere,
        "import sys, hnnbench; print(hnnbench.__file__); "
        "from hnnbench._entry.command import run; "
        "sys.exit(run(['--cfg', 'job', 'system=pendulum', 'model=oracle']))",
    )
    assert proc.stdout.splitlines()[0].startswith(str(site))
    assert "name: pendulum" in proc.stdout and "radius_min: 1.3" in proc.stdout
    _python_in(
        site,
        elsewhere,
        "import sys; from hnnbench._entry.command import run; sys.exit(run(["
        "'system=spring', 'model=oracle', 'profile=quick', 'hydra.run.dir=out']))",
    )
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
    pip_install(site, f"hnnbench @ git+file://{REPO}@{head}", "--no-build-isolation", "--no-index")
    proc = _python_in(
        site,
        elsewhere,
        "import hnnbench; from hnnbench._record.environment import git_commit; "
        "print(hnnbench.__file__); print(git_commit())",
    )
    where, commit = proc.stdout.split()
    assert where.startswith(str(site)) and commit == head, proc.stdout
