"""The SRNN rolls out as it was trained: its own leapfrog map at the training step
(``model.integrator=leapfrog``, the ranked default), the same in both backends; the
``dopri5`` variant integrates its learned field."""

from __future__ import annotations

import numpy as np
import pytest

from hnnbench._contracts.plugin import TrainSettings
from hnnbench.neural._backend import map_plan

pytest.importorskip("torch")
pytest.importorskip("jax")

from hnnbench_plugins.models.srnn import SRNNConfig, SRNNJax, SRNNTorch  # noqa: E402
from hnnbench_plugins.systems.spring import Spring, SpringConfig  # noqa: E402


def test_the_map_plan_lands_on_every_grid_time():
    t = np.array([0.0, 0.25, 0.5, 1.25, 1.3])
    m, h = map_plan(t, 0.1)
    assert m.tolist() == [3, 3, 8, 1]
    np.testing.assert_allclose(np.cumsum(m * h), t[1:] - t[0])
    assert np.all(np.abs(h) <= 0.1 + 1e-15)
    m_back, h_back = map_plan(t[::-1], 0.1)
    assert m_back.tolist() == m[::-1].tolist() and np.all(h_back < 0)
    assert map_plan(np.array([0.0, 0.3]), 0.1)[0].tolist() == [3]  # no extra step from rounding


@pytest.fixture(scope="module")
def trained():
    system = Spring(SpringConfig(name="spring", n_traj=24))
    data = system.dataset(0)
    cfg = SRNNConfig(name="srnn", hidden=16, dtype="float64")
    train = TrainSettings(steps=30, batch_size=None, lr=1e-3, weight_decay=0.0)
    tm, jm = SRNNTorch(cfg, system, "cpu"), SRNNJax(cfg, system, "cpu")
    tm.fit(data, train, 0, lambda *_: None)
    jm.fit(data, train, 0, lambda *_: None)
    return system, data, tm, jm


@pytest.mark.parametrize("window", [3, 5, 8])
def test_the_srnn_selects_on_the_systems_criterion_whatever_the_training_window(window):
    """``model.window`` sets the training windows; checkpoints are selected on the
    system's criterion, as for every family: on the noisy spring, the field at the clean
    validation inputs."""
    from hnnbench import CLEAN_INPUTS
    from hnnbench._contracts.datasets import with_validation

    system = Spring(SpringConfig(name="spring", n_traj=24))
    data = with_validation(system.dataset(0), 0)
    model = SRNNJax(SRNNConfig(name="srnn", hidden=16, window=window), system, "cpu")
    problem = model.view.problem(data, *model.training_options())
    train_windows, train_dts = problem.train
    assert train_windows.shape[1] == window and train_dts.shape[1] == window - 1
    assert (problem.criterion, problem.criterion_name) == ("field", "field_mse_clean")
    assert data.valid is not None
    np.testing.assert_array_equal(problem.valid[0], data.valid.extras[CLEAN_INPUTS])
    np.testing.assert_array_equal(problem.valid[1], data.valid.dxdt)


def test_the_leapfrog_step_is_the_training_interval(trained):
    system, data, tm, jm = trained
    assert tm.data_step == pytest.approx(system.cfg.t_end / (system.cfg.n_points - 1))
    assert tm.map_step() == jm.map_step() == pytest.approx(tm.data_step)


def test_both_backends_roll_out_the_same_map(trained):
    system, _, tm, jm = trained
    jm.set_weights(tm.get_weights())
    ev = system.evaluation(0)
    x0, t = ev.x0[:4], ev.t[:30]
    out_t, out_j = tm.rollout(x0, t), jm.rollout(x0, t)
    assert out_t.shape == (4, 30, 2)
    np.testing.assert_allclose(out_t[:, 0], x0)
    np.testing.assert_allclose(out_j, out_t, rtol=1e-10, atol=1e-12)
    back_t = tm.rollout(out_t[:, -1], t[::-1].copy())
    np.testing.assert_allclose(back_t[:, -1], x0, atol=1e-9)  # leapfrog is reversible


def test_the_map_approaches_the_learned_field_as_its_step_shrinks(trained):
    """Leapfrog is a consistent integrator of the learned field: with a small step it
    agrees with the dopri5 rollout of the same weights (the variant's)."""
    system, _, tm, _ = trained
    field = SRNNTorch(
        SRNNConfig(name="srnn", hidden=16, dtype="float64", integrator="dopri5"), system, "cpu"
    )
    field.set_weights(tm.get_weights())
    assert field.map_step() is None
    ev = system.evaluation(0)
    x0, t = ev.x0[:3], ev.t[:11]
    coarse = np.abs(tm.rollout(x0, t) - field.rollout(x0, t)).max()
    tm.data_step = 1e-3
    fine = np.abs(tm.rollout(x0, t) - field.rollout(x0, t)).max()
    assert fine < 1e-5 and fine < coarse / 100


def test_the_step_survives_save_and_load(trained, tmp_path):
    system, _, tm, _ = trained
    tm.data_step = 0.1
    tm.save(tmp_path / "w.safetensors")
    other = SRNNJax(SRNNConfig(name="srnn", hidden=16, dtype="float64"), system, "cpu")
    other.load(tmp_path / "w.safetensors")
    assert other.data_step == 0.1


def test_an_unknown_integrator_is_one_clear_error():
    from hnnbench import ConfigError

    with pytest.raises(ConfigError, match="model.integrator='rk4' is invalid"):
        SRNNConfig(name="srnn", integrator="rk4").validate()


def _reference_window_loss(step, windows, dts, substeps, stack, mean):
    """The SRNN's training loss as the plain chain of its ``step``s (each step
    evaluating its own forces)."""
    state, predictions = windows[:, 0], []
    for k in range(windows.shape[1] - 1):
        h = (dts[:, k] / substeps)[:, None]
        for _ in range(substeps):
            state = step(state, h)
        predictions.append(state)
    return mean((stack(predictions, 1) - windows[:, 1:]) ** 2)


@pytest.mark.parametrize("substeps", [1, 3])
def test_the_window_loss_is_the_chain_of_steps_in_both_backends(substeps):
    """The loss reuses each step's closing force for the next step's opening half-kick:
    the same value as chaining ``step``, with fewer gradient evaluations."""
    import jax.numpy as jnp
    import torch

    from hnnbench_plugins.models.srnn import jax as srnn_jax
    from hnnbench_plugins.models.srnn import torch as srnn_torch

    rng = np.random.default_rng(3)
    windows, dts = rng.normal(size=(6, 5, 4)), rng.uniform(0.05, 0.2, size=(6, 4))

    # T(p) = |p|²/2 + 0.1 Σp³ and V(q) = Σ(1 - cos q) + 0.05 Σq⁴ (non-linear gradients)
    jax_nets = {
        "T": lambda p: jnp.reshape(0.5 * jnp.sum(p**2) + 0.1 * jnp.sum(p**3), (1,)),
        "V": lambda q: jnp.reshape(jnp.sum(1 - jnp.cos(q)) + 0.05 * jnp.sum(q**4), (1,)),
    }
    loss_j = float(srnn_jax.window_loss(jax_nets, jnp.asarray(windows), jnp.asarray(dts), substeps))
    ref_j = float(
        _reference_window_loss(
            lambda z, h: srnn_jax.step(jax_nets, z, h),
            jnp.asarray(windows),
            jnp.asarray(dts),
            substeps,
            jnp.stack,
            jnp.mean,
        )
    )

    class Grad:  # the torch MLP's interface the implementation uses: the same T and V
        def __init__(self, grad):
            self.input_gradient = grad

    torch_nets = {
        "T": Grad(lambda p: p + 0.3 * p**2),
        "V": Grad(lambda q: torch.sin(q) + 0.2 * q**3),
    }
    w, d = torch.as_tensor(windows), torch.as_tensor(dts)
    loss_t = float(srnn_torch.window_loss(torch_nets, w, d, substeps))
    ref_t = float(
        _reference_window_loss(
            lambda z, h: srnn_torch.step(torch_nets, z, h), w, d, substeps, torch.stack, torch.mean
        )
    )
    assert loss_j == pytest.approx(ref_j, rel=1e-13)
    assert loss_t == pytest.approx(ref_t, rel=1e-13)
    assert loss_t == pytest.approx(loss_j, rel=1e-12)  # the same Hamiltonian in both
