"""A model output of the wrong shape fails its job in one line (tests/unit/test_outputs.py
checks the outputs themselves)."""

from __future__ import annotations

import numpy as np
import pytest

import hnnbench
from hnnbench import _registry as registry
from hnnbench._running.compose import compose
from hnnbench._running.job import run_job


class _Truth(hnnbench.Model):
    """The system's own field, rolled out correctly (a test's oracle): every output
    right, so each subclass below breaks exactly one."""

    version = "1"

    def fit(self, data, train, seed, progress):
        return hnnbench.FitResult(history={}, steps=0)

    def time_derivative(self, x):
        return self.system.vector_field(x)

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        return hnnbench.solve_batch(
            self.time_derivative, x0, t, rtol=rtol, atol=atol, method="RK45"
        )

    def energy(self, x):
        return self.system.energy(x)


class _OneStepRollout(_Truth):
    """Returns only the initial state, ``(M, 1, d)``: it broadcasts against ``(M, T, d)``."""

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        return np.asarray(x0, dtype=np.float64)[:, None, :]


@pytest.fixture()
def one_step_model():
    registry.register("model", "one_step_rollout", _OneStepRollout)
    yield "one_step_rollout"
    registry.MODELS._registered.pop("one_step_rollout", None)
    registry.refresh()


def test_a_rollout_of_the_wrong_shape_fails_the_job_in_one_line(one_step_model, tmp_path):
    overrides = [
        "system=spring",
        f"model={one_step_model}",
        "profile=quick",
        "save_model=false",
        "pin_cpu=false",
    ]
    record = run_job(compose(overrides), tmp_path / "job", overrides=overrides)[0].record
    assert record["status"] == "failed", record
    error = record["error"]
    assert "\n" not in error and "traceback" not in record
    assert error.startswith(f"{one_step_model}.rollout returned shape (5, 1, 2)"), error
    assert "expected (M, T, d)" in error and "(5, 100, 2)" in error
    # no metric was recorded from the broadcast arrays
    assert not record["metrics"]
