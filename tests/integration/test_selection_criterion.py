"""The validation criterion the training loop selects on (docs/METRICS.md, "Checkpoint
selection"): one per system, the same for every family and both backends; and a
diagnostic whose rollout fails never sets a run's status."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hnnbench
from hnnbench import CLEAN_INPUTS, RolloutDiverged
from hnnbench import _registry as registry
from hnnbench._contracts.datasets import with_validation
from hnnbench._running.compose import compose
from hnnbench._running.job import run_job
from hnnbench.neural import _views as views

pytest.importorskip("torch")
pytest.importorskip("jax")

from hnnbench_plugins.models.hnn import HNNJax  # noqa: E402
from hnnbench_plugins.models.lnn import LNNJax, LNNTorch  # noqa: E402
from hnnbench_plugins.models.srnn import SRNNJax, SRNNTorch  # noqa: E402
from hnnbench_plugins.systems.double_pendulum import (  # noqa: E402
    DoublePendulum,
    DoublePendulumConfig,
)
from hnnbench_plugins.systems.spring import Spring, SpringConfig  # noqa: E402


def _system(cls, cfg_cls, **kw):
    cfg = cfg_cls(name=cls.__name__.lower(), **kw)
    return cls(cfg)


def test_a_noisy_system_selects_on_the_field_at_its_clean_inputs():
    system = _system(Spring, SpringConfig, n_traj=24)
    data = with_validation(system.dataset(0), 0)
    model = HNNJax(HNNJax.Config(name="hnn_jax", hidden=8), system, "cpu")
    problem = model.view.problem(data)
    assert (problem.criterion, problem.criterion_name) == ("field", "field_mse_clean")
    assert data.valid is not None
    np.testing.assert_array_equal(problem.valid[0], data.valid.extras[CLEAN_INPUTS])
    assert not np.array_equal(problem.valid[0], data.valid.x)  # not the noisy inputs


def test_a_second_order_family_is_scored_in_the_systems_coordinates():
    """The double pendulum's mass matrix depends on q: the weights map an error of
    (q̇, q̈) to the error of (q̇, ṗ) that canonical_rate gives, point by point."""
    system = _system(DoublePendulum, DoublePendulumConfig, n_traj=6)
    data = with_validation(system.dataset(0), 0)
    model = LNNJax(LNNJax.Config(name="lnn_jax", hidden=8), system, "cpu")
    problem = model.view.problem(data)
    assert problem.criterion == "field:weighted" and problem.criterion_name == "field_mse"
    z, zdot, weights = problem.valid
    rng = np.random.default_rng(0)
    predicted = zdot + rng.normal(size=zdot.shape)
    kin = system.kinematics()
    expected = kin.canonical_rate(z, predicted) - kin.canonical_rate(z, zdot)
    np.testing.assert_allclose(
        np.einsum("vij,vj->vi", weights, predicted - zdot), expected, rtol=1e-9, atol=1e-9
    )
    np.testing.assert_allclose(kin.canonical_rate(z, zdot), data.valid.dxdt, rtol=1e-9, atol=1e-9)


def test_the_backends_compute_the_same_criterion():
    """Every criterion kind, torch and JAX on the same weights, float64: the same
    per-point values (the field, weighted; windows by RK4 and by the SRNN's map)."""
    import torch

    from hnnbench.neural.jax import criterion_values
    from hnnbench.neural.jax._nets import nets_from_weights
    from hnnbench.neural.torch import make_criterion

    system = _system(DoublePendulum, DoublePendulumConfig, n_traj=6)
    data = with_validation(system.dataset(0), 0)
    cases = [(LNNTorch, LNNJax, {}, "field:weighted"), (SRNNTorch, SRNNJax, {"window": 3}, "field")]
    for torch_cls, jax_cls, extra, kind in cases:
        cfg = torch_cls.Config(name="m", hidden=8, dtype="float64", **extra)
        tm, jm = torch_cls(cfg, system, "cpu"), jax_cls(cfg, system, "cpu")
        problem = tm.view.problem(data, *tm.training_options())
        assert problem.criterion == kind
        windows = views.trajectory_windows(data.valid, tm.view.to_model(data.valid.x), 3, stride=2)
        weights = tm.initial_weights(1)
        layout = tm.layout()
        params = {k: torch.tensor(v, dtype=torch.float64) for k, v in weights.items()}
        nets = nets_from_weights(weights, layout, cfg.layers, cfg.activation, np.dtype("float64"))
        for criterion, arrays, options in (
            (problem.criterion, problem.valid, ()),
            ("windows:rk4", windows, (("substeps", 4),)),
            *((("windows:map", windows, (("substeps", 2),)),) if hasattr(tm._impl, "step") else ()),
        ):
            got_t = make_criterion(tm._impl, criterion, layout, cfg, options)(
                params, *(torch.tensor(a, dtype=torch.float64) for a in arrays)
            )
            got_j = criterion_values(criterion, jm._impl, options, nets, *arrays)
            assert got_t.shape == (arrays[0].shape[0],)
            np.testing.assert_allclose(
                got_t.numpy(),
                np.asarray(got_j),
                rtol=1e-8,
                atol=1e-12,
                err_msg=f"{torch_cls.__name__} {criterion}",
            )


def test_measured_data_selects_on_short_rollouts(tmp_path, monkeypatch):
    from conftest import shared_data_dir

    from hnnbench_plugins.systems.real_pendulum import RealPendulum, RealPendulumConfig

    if not (shared_data_dir() / "real_pend_h_1.txt").is_file():
        pytest.skip("no measured data")
    monkeypatch.setenv("HNNBENCH_DATA_DIR", str(shared_data_dir()))
    monkeypatch.setenv("HNNBENCH_CACHE_DIR", str(tmp_path))
    system = RealPendulum(RealPendulumConfig(name="real_pendulum"))
    data = system.dataset(0)
    assert data.valid is not None
    for cls, integrator in ((HNNJax, "rk4"), (SRNNJax, "map")):
        model = cls(cls.Config(name="m", hidden=8), system, "cpu")
        problem = model.view.problem(data, *model.training_options(), integrator=integrator)
        windows, dts = problem.valid
        assert problem.criterion == f"windows:{integrator}"
        assert problem.criterion_name == "rollout_q_mse_4"
        assert windows.shape[1:] == (5, 2) and dts.shape[1] == 4
        # windows share only their ends: each starts where the previous one ended
        starts = [int(np.flatnonzero(np.all(data.valid.x == w[0], axis=1))[0]) for w in windows]
        assert min(np.diff(starts)) >= 4


class _StallsWhenReversed(hnnbench.Model):
    """The true spring, except that a rollout from momentum-flipped states gives up
    (as the two-body LNN's did on states outside its training data)."""

    def fit(self, data, train, seed, progress):
        return hnnbench.FitResult(history={}, steps=0)

    def time_derivative(self, x):
        return self.system.vector_field(x)

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        if getattr(self, "_rolled", False):
            raise RolloutDiverged("the step size fell below 1e-8 of the span (forced)")
        self._rolled = True
        return hnnbench.solve_batch(
            self.time_derivative, x0, t, rtol=rtol, atol=atol, method="RK45"
        )


@pytest.fixture()
def stalling_model():
    registry.register("model", "stalls_when_reversed", _StallsWhenReversed)
    yield "stalls_when_reversed"
    registry.MODELS._registered.pop("stalls_when_reversed", None)
    registry.refresh()


def test_a_failing_diagnostic_leaves_the_run_ok(stalling_model, tmp_path):
    overrides = [
        "system=spring",
        f"model={stalling_model}",
        "profile=quick",
        "save_model=false",
        "pin_cpu=false",
    ]
    record = run_job(compose(overrides), tmp_path / "job", overrides=overrides)[0].record
    assert record["status"] == "ok", record.get("error")
    assert record["metrics"]["reversibility_error"]["mean"] == math.inf
    assert record["metric_errors"]["reversibility_error"].startswith("rollout failed:")
    assert "forced" in record["metric_errors"]["reversibility_error"]
    assert math.isfinite(record["metrics"]["rollout_mse"]["mean"])
