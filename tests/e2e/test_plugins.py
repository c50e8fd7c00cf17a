"""A real third-party plugin package (tests/plugin_pkg), pip-installed into a temporary
site directory, joins `list`, `all` and sweeps without any YAML in this repo."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pandas as pd
import pytest
from conftest import REPO, hnnbench, install_test_package


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    site, env = install_test_package("plugin_pkg", tmp_path_factory)
    assert list(site.glob("hnnbench_toy_plugin-0.3.0.dist-info/entry_points.txt"))
    return env


def test_plugin_appears_in_list(plugin_env):
    proc = hnnbench("list", "--json", env=plugin_env)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    quartic = next(s for s in data["system"] if s["name"] == "quartic")
    model = next(m for m in data["model"] if m["name"] == "linear_lstsq")
    assert quartic["status"] == model["status"] == "ok"
    assert quartic["version"] == "3" and quartic["package"] == "hnnbench-toy-plugin 0.3.0"
    assert model["backend"] == "numpy"
    # Built-ins are still there.
    assert {"spring", "pendulum"} <= {s["name"] for s in data["system"]}


def test_all_includes_plugin(plugin_env):
    code = (
        "from hnnbench._sweeping.plan import plan; "
        "print(' '.join(plan(['-m', 'system=all', 'model=all']).argv))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={**os.environ, **plugin_env},
        check=True,
    ).stdout
    system_arg = next(a for a in out.split() if a.startswith("system="))
    model_arg = next(a for a in out.split() if a.startswith("model="))
    assert "quartic" in system_arg.split("=")[1].split(",")
    assert "linear_lstsq" in model_arg.split("=")[1].split(",")


@pytest.mark.slow
def test_plugin_runs_in_a_sweep(plugin_env, tmp_path):
    sweep = tmp_path / "sweep"
    proc = hnnbench(
        "-m",
        "system=quartic,spring",
        "model=linear_lstsq,oracle",
        "profile=quick",
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
        env=plugin_env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    recs = [json.loads(p.read_text()) for p in sweep.rglob("result.json")]
    assert sorted((r["system"], r["model"]) for r in recs) == [
        ("quartic", "linear_lstsq"),
        ("quartic", "oracle"),
        ("spring", "linear_lstsq"),
        ("spring", "oracle"),
    ]
    assert all(r["status"] == "ok" for r in recs), [r["error"] for r in recs]
    quartic = next(r for r in recs if r["system"] == "quartic" and r["model"] == "oracle")
    assert quartic["system_version"] == "3"
    assert quartic["config"]["system"]["n_traj"] == 10  # the plugin's own quick profile


@pytest.mark.slow
def test_a_held_out_plugin_gets_its_rank_from_check(plugin_env, tmp_path):
    """A new user's path: the plugin's quick sweep, checked against the CI reference with
    --allow-missing, gets a line naming its model and its rank among the reference's
    families, a verdict, and one line for the pairs it did not run."""
    sweep = tmp_path / "sweep"
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=linear_lstsq",
        "profile=quick",
        "seed=0",
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
        env=plugin_env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    reference = REPO / "results" / "reference" / "quick.csv"
    check = hnnbench(
        "check", str(sweep), "--reference", str(reference), "--allow-missing", env=plugin_env
    )
    assert check.returncode == 0, check.stdout[-3000:] + check.stderr[-2000:]
    lines = [line.strip() for line in check.stdout.splitlines()]
    families = (
        len({f for f in pd.read_csv(reference).query("system == 'spring' and ranked")["family"]})
        + 1
    )
    rank = next(ln for ln in lines if ln.startswith("spring energy_mse: linear_lstsq ranks "))
    assert f" of {families} families (1 seed: no interval): " in rank
    assert any(ln.startswith("verdict: linear_lstsq ranks first on ") for ln in lines)
    assert len([ln for ln in lines if ln.startswith("missing:")]) == 1
