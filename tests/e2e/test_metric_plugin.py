"""A third-party metric package (tests/metric_pkg), pip-installed into a temporary site
directory: its metric is computed for every model, shows in the leaderboard, and gates
``hnnbench check``, with no change to hnnbench."""

from __future__ import annotations

import json

import pytest
from conftest import hnnbench, install_test_package


@pytest.fixture(scope="module")
def metric_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    return install_test_package("metric_pkg", tmp_path_factory)[1]


def test_the_metric_is_listed(metric_env):
    proc = hnnbench("list", "--json", env=metric_env)
    assert proc.returncode == 0, proc.stderr
    metrics = {m["name"]: m for m in json.loads(proc.stdout)["metric"]}
    assert metrics["final_state_error"]["status"] == "ok"
    assert metrics["final_state_error"]["package"] == "hnnbench-metric-plugin 0.1.0"
    assert {"energy_mse", "reversibility_error", "vpt_lyapunov"} <= set(metrics)


@pytest.mark.slow
def test_the_metric_reaches_records_leaderboard_and_check(metric_env, tmp_path):
    sweep = tmp_path / "sweep"
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=mlp_jax,oracle",
        "profile=quick",
        "system.steps=50",
        "system.eval_n_traj=3",
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
        env=metric_env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    recs = {
        json.loads(p.read_text())["model"]: json.loads(p.read_text())
        for p in sweep.rglob("result.json")
    }
    mlp = recs["mlp_jax"]["metrics"]["final_state_error"]["mean"]
    oracle = recs["oracle"]["metrics"]["final_state_error"]["mean"]
    # computed for every model, by the core (quick rollouts: tolerances 1e-6)
    assert oracle < 1e-7 < mlp
    board = (sweep / "leaderboard.csv").read_text()
    assert "final_state_error_mean" in board.splitlines()[0]
    reference = tmp_path / "ref.csv"
    assert (
        hnnbench(
            "check", str(sweep), "--reference", str(reference), "--update", env=metric_env
        ).returncode
        == 0
    )
    assert (
        hnnbench("check", str(sweep), "--reference", str(reference), env=metric_env).returncode == 0
    )
    # worse on the plugin's metric only: the gate names it (its declared rule: 10x)
    (path,) = (sweep / "spring" / "mlp_jax").rglob("result.json")
    rec = json.loads(path.read_text())
    rec["metrics"]["final_state_error"]["mean"] = mlp * 100
    path.write_text(json.dumps(rec))
    proc = hnnbench("check", str(sweep), "--reference", str(reference), env=metric_env)
    assert proc.returncode == 1
    assert "final_state_error" in proc.stdout and "100x worse" in proc.stdout
