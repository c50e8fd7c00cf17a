"""End-to-end sweeps through the real console script and Hydra (slow)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import QUICK_ORACLE_BOUND, hnnbench

from hnnbench import _registry as registry

pytestmark = pytest.mark.slow


def _records(root: Path) -> dict[tuple, dict]:
    out = {}
    for path in root.rglob("result.json"):
        rec = json.loads(path.read_text())
        out[(rec["system"], rec["model"], rec["seed"])] = rec
    return out


def test_quick_sweep_spring_pendulum_then_resume(tmp_path):
    sweep = tmp_path / "sweep"
    args = [
        "-m",
        "system=spring,pendulum",
        "model=mlp_torch,hnn_torch,oracle",
        "profile=quick",
        f"hydra.sweep.dir={sweep}",
    ]
    proc = hnnbench(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    recs = _records(sweep)
    assert len(recs) == 6
    declared = registry.discover("metric")
    assert {"train_loss", "energy_mse", "reversibility_error", "energy_drift_long"} <= set(declared)
    for key, rec in recs.items():
        assert rec["status"] == "ok", (key, rec["error"])
        # Every declared metric (the built-in ones at least), NaN where not applicable.
        assert set(declared) <= set(rec["metrics"]), (key, set(declared) - set(rec["metrics"]))
        assert rec["environment"]["python"] and rec["config"]["seed"] == 0
        assert set(rec["timings"]) >= {"data_s", "fit_s", "eval_s", "total_s", "cpu_s"}
        assert rec["timings"]["cpu_s"] > 0
    # The oracle is the floor of the evaluation pipeline.
    assert recs[("spring", "oracle", 0)]["metrics"]["energy_mse"]["mean"] < QUICK_ORACLE_BOUND
    assert "| system" in proc.stdout and "6 jobs: 6 ok" in proc.stdout
    assert (sweep / "summary.csv").exists()

    # Resume: the same command into the same directory redoes nothing.
    before = {k: r["created_at"] for k, r in recs.items()}
    proc = hnnbench(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (proc.stdout + proc.stderr).count("already finished") == 6  # job log: stdout
    assert {k: r["created_at"] for k, r in _records(sweep).items()} == before
