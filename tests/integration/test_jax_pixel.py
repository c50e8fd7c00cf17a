"""The JAX models on the pixel pendulum: autoencoder + latent dynamics (PixelView)."""

from __future__ import annotations

import numpy as np
import pytest

from hnnbench._contracts.datasets import with_validation
from hnnbench._contracts.plugin import TrainSettings
from hnnbench_plugins.systems.pixel_pendulum import PixelPendulum, PixelPendulumConfig

pytest.importorskip("jax")
pytest.importorskip("equinox")
pytest.importorskip("optax")
pytest.importorskip("diffrax")

P = 28 * 28


def small_system() -> PixelPendulum:
    cfg = PixelPendulumConfig(
        name="pixel_pendulum", n_traj=10, n_frames=8, eval_n_traj=3, eval_n_points=6
    )
    cfg.validate()
    return PixelPendulum(cfg)


@pytest.fixture(scope="module")
def tiny():
    """A tiny pixel dataset and both JAX models fitted for a few steps."""
    from hnnbench.neural import NeuralConfig
    from hnnbench_plugins.models.hnn import HNNJax
    from hnnbench_plugins.models.mlp import MLPJax

    system = small_system()
    data, ev = system.dataset(0), system.evaluation(0)
    train = TrainSettings(steps=6, batch_size=16, lr=1e-3, weight_decay=1e-5)
    models = {}
    for cls in (MLPJax, HNNJax):
        assert cls.unsupported_reason(system) is None
        model = cls(NeuralConfig(name=cls.__name__, hidden=16, log_every=3), system, device="cpu")
        logged: list[int] = []
        result = model.fit(
            data, train, seed=0, progress=lambda step, _m, out=logged: out.append(step)
        )
        assert result.steps == 6 and logged == [3, 6]
        assert np.all(np.isfinite(result.history["train_loss"]))
        model.history, model.selection = result.history, result.selection
        models[cls.__name__] = model
    return system, data, ev, models


@pytest.mark.parametrize("name", ["MLPJax", "HNNJax"])
def test_jax_pixel_model_shapes_and_finiteness(tiny, name):
    _system, data, ev, models = tiny
    model = models[name]
    assert model.view.time_unit == data.meta["dt"]
    z0 = model.encode(ev.observations[:, 0])
    assert z0.shape == (3, 2) and z0.dtype == np.float64 and np.all(np.isfinite(z0))
    zhat = model.rollout(z0, ev.t)
    assert zhat.shape == (3, ev.t.shape[0], 2) and np.all(np.isfinite(zhat))
    np.testing.assert_allclose(zhat[:, 0], z0)
    frames = model.decode(zhat.reshape(-1, 2))
    assert frames.shape == (3 * ev.t.shape[0], 2 * P) and np.all(np.isfinite(frames))
    assert model.time_derivative(z0).shape == (3, 2)
    loss = model.loss(data.test.x, data.test.dxdt)
    assert np.isfinite(loss) and loss > 0
    # loss() recovers x_next from dxdt; the tiny validation set is logged whole, and the
    # model holds the selected checkpoint: its logged validation loss is loss() on it
    valid = with_validation(data, 0).valid
    at = model.history["step"].index(model.selection.step)
    assert model.history["val_loss"][at] == pytest.approx(model.loss(valid.x, valid.dxdt), rel=1e-4)
    energy = model.energy(z0)
    assert (energy is None) == (name == "MLPJax")
    if energy is not None:
        assert energy.shape == (3,)


@pytest.mark.parametrize("name", ["MLPJax", "HNNJax"])
def test_jax_pixel_time_units(tiny, name):
    """Rollouts are in system time: their initial slope is time_derivative."""
    _system, _data, ev, models = tiny
    model = models[name]
    z0 = model.encode(ev.observations[:, 0])
    h = 1e-5
    zhat = model.rollout(z0, np.array([0.0, h]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        (zhat[:, 1] - z0) / h, model.time_derivative(z0), rtol=1e-3, atol=1e-6
    )


@pytest.mark.parametrize("name", ["MLPJax", "HNNJax"])
def test_jax_pixel_save_load_round_trip(tiny, tmp_path, name):
    system, _data, ev, models = tiny
    model = models[name]
    path = tmp_path / "weights.safetensors"
    model.save(path)
    clone = type(model)(model.cfg, system, device="cpu")
    clone.load(path)
    assert clone.view.time_unit == model.view.time_unit
    obs = ev.observations[:, 0]
    np.testing.assert_array_equal(clone.encode(obs), model.encode(obs))
    z0 = model.encode(obs)
    np.testing.assert_array_equal(clone.decode(z0), model.decode(z0))
    np.testing.assert_allclose(clone.rollout(z0, ev.t), model.rollout(z0, ev.t))


def test_jax_pixel_end_to_end(tmp_path):
    from conftest import compose_job as compose

    from hnnbench._running.job import run_job

    # the fixture's data, network and chunk shapes: the compiled steps and solver are reused
    overrides = [
        "system=pixel_pendulum",
        "model=hnn_jax",
        "profile=quick",
        "system.steps=21",
        "system.n_traj=10",
        "system.n_frames=8",
        "system.eval_n_traj=3",
        "system.eval_n_points=6",
        "system.batch_size=16",
        "model.hidden=16",
        "model.log_every=3",
        "device=cpu",
    ]
    record = run_job(compose(overrides), tmp_path / "job", overrides=overrides)[0].record
    assert record["status"] == "ok", record
