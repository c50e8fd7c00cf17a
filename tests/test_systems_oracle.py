"""The new built-in systems end to end with the oracle: the true field integrated by the
core's evaluation must reproduce each system's energy and trajectories, to within the
rollout tolerance of the profile (paper: rtol 1e-9; quick: 1e-6, conf/profile/quick.yaml)."""

from __future__ import annotations

import pytest
from conftest import QUICK_ORACLE_BOUND

from hnnbench.config import compose
from hnnbench.job import run_job

SIMULATED = ["double_pendulum", "damped_spring", "damped_pendulum", "spring_chain"]
#: Energy and rollout MSE bounds by profile.
BOUND = {"paper": 1e-10, "quick": QUICK_ORACLE_BOUND}


@pytest.mark.parametrize("profile", ["quick", "paper"])
@pytest.mark.parametrize("system", SIMULATED)
def test_oracle_reproduces_the_energy(tmp_path, system, profile):
    overrides = [f"system={system}", "model=oracle", f"profile={profile}"]
    record = run_job(compose(overrides), tmp_path / "job", overrides=overrides)
    assert record["status"] == "ok", record["error"]
    metrics = record["metrics"]
    assert metrics["energy_mse"]["mean"] < BOUND[profile]
    assert metrics["test_loss"]["mean"] < 1e-20 or system.startswith("damped")  # noisy inputs
    assert metrics["rollout_mse"]["mean"] < BOUND[profile]


def test_the_oracle_is_skipped_on_measured_data(tmp_path):
    overrides = ["system=real_double_pendulum", "model=oracle", "profile=quick"]
    record = run_job(compose(overrides), tmp_path / "job", overrides=overrides)
    assert record["status"] == "skipped"
    assert "no known vector field" in record["error"]
