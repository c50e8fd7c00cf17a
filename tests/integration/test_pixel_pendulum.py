"""Pixel pendulum: renderer, data, evaluation trajectories, and the torch pixel models."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hnnbench._contracts.datasets import with_validation
from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.plugin import TrainSettings
from hnnbench_plugins.systems.pendulum import Pendulum, PendulumConfig
from hnnbench_plugins.systems.pixel_pendulum import (
    PixelPendulum,
    PixelPendulumConfig,
    render,
)

SIDE = 28
P = SIDE * SIDE


def small_system(**overrides) -> PixelPendulum:
    values = {
        "name": "pixel_pendulum",
        "n_traj": 10,
        "n_frames": 8,
        "eval_n_traj": 3,
        "eval_n_points": 6,
        **overrides,
    }
    cfg = PixelPendulumConfig(**values)
    cfg.validate()
    return PixelPendulum(cfg)


def centroid(frames: np.ndarray) -> np.ndarray:
    """``(N, 2)`` (column, row) centres of mass, in pixels from the image centre."""
    grid = np.arange(SIDE) + 0.5 - SIDE / 2
    mass = frames.sum(axis=(1, 2))
    col = (frames.sum(axis=1) * grid).sum(axis=1) / mass
    row = (frames.sum(axis=2) * grid).sum(axis=1) / mass
    return np.stack([col, row], axis=1)


# --------------------------------------------------------------------------- renderer


def test_render_shape_range_and_antialiasing():
    q = np.linspace(-np.pi, np.pi, 37)
    frames = render(q)
    assert frames.shape == (37, SIDE, SIDE) and frames.dtype == np.float32
    assert frames.min() >= 0.0 and frames.max() <= 1.0
    assert frames.max() == 1.0  # the bob's interior is fully covered
    grey = (frames > 0.02) & (frames < 0.98)
    assert grey.sum(axis=(1, 2)).min() >= 10  # every frame has anti-aliased edge pixels
    # the drawn area does not depend on the angle (rotation only moves the shape)
    mass = frames.sum(axis=(1, 2))
    assert np.ptp(mass) / mass.mean() < 0.03


def test_render_bob_moves_with_q():
    c = centroid(render(np.array([0.0, 0.5, -0.5, np.pi / 2, np.pi])))
    assert c[0, 1] > 5 and abs(c[0, 0]) < 0.1  # q = 0: hanging straight down
    assert c[1, 0] > 2 and c[2, 0] < -2  # q > 0 to the right, q < 0 to the left
    assert c[3, 0] > 5 and abs(c[3, 1]) < 0.5  # q = pi/2: horizontal, to the right
    assert c[4, 1] < -5  # q = pi: straight up
    # small changes of q move pixels a little, continuously (sub-pixel sensitivity)
    a, b = render(np.array([0.3, 0.3 + 1e-3]))
    assert 0 < np.abs(a - b).max() < 0.05


def test_render_supersampling_agrees():
    q = np.linspace(-2, 2, 9)
    assert np.abs(render(q, supersample=1) - render(q, supersample=4)).mean() < 0.01


# --------------------------------------------------------------------------- data


def test_dataset_shapes_splits_and_extras():
    system = small_system()
    c = system.cfg
    data = system.dataset(0)
    per_traj = c.n_frames - 2
    n_test = round(c.n_traj * c.test_split)
    assert data.test.x.shape == (n_test * per_traj, 2 * P)
    assert data.train.x.shape == ((c.n_traj - n_test) * per_traj, 2 * P)
    assert data.meta["dt"] == c.dt
    # the first 20 % of the trials are the test set
    assert set(data.test.traj) == set(range(n_test))
    assert set(data.train.traj) == set(range(n_test, c.n_traj))
    for split in (data.train, data.test):
        n = len(split)
        assert split.extras["state"].shape == (n, 2)
        assert split.extras["state"].dtype == np.float64
        assert split.extras["x_next"].shape == (n, 2 * P)
        assert split.t.shape == split.traj.shape == (n,)
        assert 0.0 <= split.x.min() and split.x.max() <= 1.0
        np.testing.assert_allclose(split.dxdt, (split.extras["x_next"] - split.x) / c.dt, atol=1e-5)
        # x = (frame_k, frame_k+1), x_next = (frame_k+1, frame_k+2)
        np.testing.assert_array_equal(split.x[:, P:], split.extras["x_next"][:, :P])
        # the first frame of x is the render of the recorded state's angle
        np.testing.assert_allclose(
            split.x[:, :P], render(split.extras["state"][:, 0]).reshape(n, P), atol=1e-6
        )
        # the true energy is conserved along each trial
        energy = system.energy(split.extras["state"]).reshape(-1, per_traj)
        assert np.ptp(energy, axis=1).max() < 1e-7
        np.testing.assert_allclose(split.t.reshape(-1, per_traj)[0], np.arange(per_traj) * c.dt)


def test_energy_and_initial_states_are_the_pendulums():
    system = small_system()
    pendulum = Pendulum(PendulumConfig(name="pendulum"))
    x = np.random.default_rng(0).normal(size=(20, 2))
    np.testing.assert_allclose(system.energy(x), 3 * (1 - np.cos(x[:, 0])) + x[:, 1] ** 2)
    np.testing.assert_allclose(system.vector_field(x), pendulum.vector_field(x))
    radius = np.linalg.norm(system.dataset(0).train.extras["state"].reshape(8, 6, 2)[:, 0], axis=1)
    assert np.all((radius >= system.cfg.radius_min) & (radius <= system.cfg.radius_max))
    assert system.pendulum.cfg.radius_max == system.cfg.radius_max
    assert system.observation == "pixels" and system.dof == 1


def test_data_and_evaluation_are_deterministic():
    system = small_system()
    a, b, other = system.dataset(0), system.dataset(0), system.dataset(1)
    np.testing.assert_array_equal(a.train.x, b.train.x)
    np.testing.assert_array_equal(a.test.extras["state"], b.test.extras["state"])
    assert not np.array_equal(a.train.extras["state"], other.train.extras["state"])
    e1, e2 = system.evaluation(0), system.evaluation(0)
    np.testing.assert_array_equal(e1.observations, e2.observations)
    # evaluation trials are fresh draws, not the data's
    assert not np.allclose(e1.states[:, 0], a.test.extras["state"][:3])


def test_evaluation_trajectories():
    system = small_system()
    ev = system.evaluation(0)
    m, t = system.cfg.eval_n_traj, system.cfg.eval_n_points
    assert ev.states.shape == (m, t, 2) and ev.observations.shape == (m, t, 2 * P)
    assert ev.dt == system.cfg.dt
    np.testing.assert_allclose(ev.t, np.arange(t) * system.cfg.dt)
    np.testing.assert_array_equal(ev.observations[:, 1:, :P], ev.observations[:, :-1, P:])
    np.testing.assert_allclose(
        ev.observations[:, :, :P].reshape(-1, P),
        render(ev.states[..., 0].reshape(-1)).reshape(-1, P),
        atol=1e-6,
    )


@pytest.mark.parametrize(
    "override",
    [
        {"n_frames": 2},
        {"test_split": 1.0},
        {"dt": 0.0},
        {"n_traj": 2, "test_split": 0.1},
        {"radius_min": 2.0, "radius_max": 1.0},
        {"side": 4},
        {"batch_size": 0},
    ],
)
def test_config_validation_is_one_line(override):
    cfg = PixelPendulumConfig(name="pixel_pendulum", **override)
    with pytest.raises(ConfigError) as err:
        cfg.validate()
    assert "\n" not in str(err.value)


def test_profiles_are_valid_and_paper_defaults():
    cfg = PixelPendulumConfig(name="pixel_pendulum")
    assert (cfg.n_traj, cfg.n_frames, cfg.side, cfg.test_split) == (200, 103, 28, 0.2)
    assert (cfg.steps, cfg.batch_size, cfg.weight_decay) == (10000, 200, 1e-5)
    for overrides in PixelPendulum.profiles.values():
        dataclasses.replace(cfg, **overrides).validate()


# --------------------------------------------------------------------------- models


@pytest.fixture(scope="module")
def tiny():
    """A tiny pixel dataset and both torch models fitted for a few steps."""
    pytest.importorskip("torch")
    from hnnbench.neural import NeuralConfig
    from hnnbench_plugins.models.hnn import HNNTorch
    from hnnbench_plugins.models.mlp import MLPTorch

    system = small_system()
    data, ev = system.dataset(0), system.evaluation(0)
    train = TrainSettings(steps=6, batch_size=16, lr=1e-3, weight_decay=1e-5)
    models = {}
    for cls in (MLPTorch, HNNTorch):
        assert cls.unsupported_reason(system) is None
        model = cls(NeuralConfig(name=cls.__name__, hidden=16), system, device="cpu")
        logged: list[int] = []
        result = model.fit(
            data, train, seed=0, progress=lambda step, _m, out=logged: out.append(step)
        )
        assert result.steps == 6 and logged[-1] == 6
        assert np.all(np.isfinite(result.history["train_loss"]))
        model.history, model.selection = result.history, result.selection
        models[cls.__name__] = model
    return system, data, ev, models


@pytest.mark.parametrize("name", ["MLPTorch", "HNNTorch"])
def test_pixel_model_shapes_and_finiteness(tiny, name):
    system, data, ev, models = tiny
    model = models[name]
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
    energy = model.energy(z0)
    assert (energy is None) == (name == "MLPTorch")
    if energy is not None:
        assert energy.shape == (3,)


@pytest.mark.parametrize("name", ["MLPTorch", "HNNTorch"])
def test_pixel_model_time_units(tiny, name):
    """Rollouts are in system time: their initial slope is time_derivative."""
    _system, _data, ev, models = tiny
    model = models[name]
    z0 = model.encode(ev.observations[:, 0])
    h = 1e-5
    zhat = model.rollout(z0, np.array([0.0, h]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        (zhat[:, 1] - z0) / h, model.time_derivative(z0), rtol=1e-3, atol=1e-6
    )


def test_pixel_loss_matches_training_objective(tiny):
    """loss(x, dxdt) recovers x_next = x + dt * dxdt: equal to the logged test loss."""
    _system, data, _ev, models = tiny
    for model in models.values():
        logged = model.loss(data.test.x, data.test.dxdt)
        x_next = data.test.extras["x_next"]
        exact = model._infer().objective(data.test.x, x_next)
        assert logged == pytest.approx(exact, rel=1e-5)
        # the tiny validation set is logged whole, and the model holds the selected
        # checkpoint: its logged validation loss is loss() on it
        valid = with_validation(data, 0).valid
        at = model.history["step"].index(model.selection.step)
        assert model.history["val_loss"][at] == pytest.approx(
            model.loss(valid.x, valid.dxdt), rel=1e-5
        )


@pytest.mark.parametrize("name", ["MLPTorch", "HNNTorch"])
def test_pixel_model_save_load_round_trip(tiny, tmp_path, name):
    system, data, ev, models = tiny
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


def test_state_systems_still_use_the_plain_models():
    pytest.importorskip("torch")
    from hnnbench.neural import NeuralConfig
    from hnnbench_plugins.models.hnn import HNNTorch

    system = Pendulum(PendulumConfig(name="pendulum", n_traj=4, n_points=10))
    model = HNNTorch(NeuralConfig(name="hnn_torch", hidden=16), system, device="cpu")
    model.fit(system.dataset(0), TrainSettings(3, None, 1e-3, 0.0), 0, lambda *_: None)
    x = system.dataset(0).test.x
    np.testing.assert_array_equal(model.encode(x), x)
    assert model.decode(x) is None
    assert model.rollout(x[:2], np.linspace(0, 1, 5)).shape == (2, 5, 2)
