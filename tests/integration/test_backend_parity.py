"""The JAX models are twins of the PyTorch models: same seed -> same initial weights
and minibatches -> same training curve and same rollouts.

Both backends build their seeded initial weights from the same numpy draws
(:func:`hnnbench.neural._init.init_arrays`) and draw minibatches from the same
stream (:class:`~hnnbench.neural._init.BatchStream`). Here they train in
float64 on the spring training set (750 points, paper architecture), full batch and
minibatch, and log every step.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("jax")
pytest.importorskip("diffrax")

import jax.numpy as jnp  # noqa: E402
import optax  # noqa: E402
import torch  # noqa: E402

from hnnbench._contracts.datasets import with_validation  # noqa: E402
from hnnbench._contracts.errors import RolloutDiverged  # noqa: E402
from hnnbench._contracts.plugin import Dataset, TrainSettings  # noqa: E402
from hnnbench.neural import NeuralConfig
from hnnbench_plugins.models.dhnn import DHNNJax, DHNNTorch  # noqa: E402
from hnnbench_plugins.models.hnn import HNNJax, HNNTorch  # noqa: E402
from hnnbench_plugins.models.lnn import LNNJax, LNNTorch  # noqa: E402
from hnnbench_plugins.models.mlp import MLPJax, MLPTorch  # noqa: E402
from hnnbench_plugins.models.so_mlp import SOMLPJax, SOMLPTorch  # noqa: E402
from hnnbench_plugins.models.srnn import SRNNJax, SRNNTorch  # noqa: E402
from hnnbench_plugins.systems.spring import Spring, SpringConfig  # noqa: E402

PAIRS = [
    (MLPTorch, MLPJax),
    (HNNTorch, HNNJax),
    (DHNNTorch, DHNNJax),
    (LNNTorch, LNNJax),
    (SOMLPTorch, SOMLPJax),
    (SRNNTorch, SRNNJax),
]
STEPS = 50
SEED = 0


@pytest.fixture(scope="module", autouse=True)
def _one_torch_thread():
    """These problems are tiny: one thread is faster, and immune to the stalls torch's
    thread pool suffers on a CPU shared with other processes."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def spring() -> Spring:
    return Spring(SpringConfig(name="spring"))


@pytest.fixture(scope="module")
def data(spring: Spring) -> Dataset:
    data = spring.dataset(SEED)
    assert len(data.train) == 750
    return data


def torch_state(model) -> dict[str, np.ndarray]:
    return model.get_weights()


def built_weights(model, data: Dataset, seed: int) -> dict[str, np.ndarray]:
    """The weights a model's backend builds from its seeded initial arrays, read back
    before any training step."""
    problem = model.view.problem(with_validation(data, seed))
    init = [model.initial_weights(seed)]
    train = TrainSettings(steps=1, batch_size=None, lr=1e-3, weight_decay=0.0)
    trainer = model._backend.trainer(
        model.family, model._impl, problem, init, train, model.layout()
    )
    (weights,) = model._backend.weights(trainer)
    return weights


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize(("torch_cls", "jax_cls"), PAIRS)
def test_same_seed_same_initial_weights(
    torch_cls, jax_cls, spring: Spring, data: Dataset, dtype: str
):
    cfg = torch_cls.Config(name="parity", dtype=dtype)
    tm, jm = torch_cls(cfg, spring, "cpu"), jax_cls(cfg, spring, "cpu")
    for seed in (0, 7):
        t_state = built_weights(tm, data, seed)
        j_state = built_weights(jm, data, seed)
        assert t_state.keys() == j_state.keys()
        for key, value in t_state.items():
            assert value.dtype == np.dtype(dtype)
            np.testing.assert_array_equal(value, j_state[key])
    other = built_weights(tm, data, 1)
    net = next(iter(tm.network_shapes()))
    assert not np.array_equal(other[f"{net}.linears.1.weight"], t_state[f"{net}.linears.1.weight"])


@pytest.fixture(
    scope="module",
    params=[(*pair, batch) for pair in PAIRS for batch in (None, 100)],
    ids=lambda p: f"{p[1].__name__}-batch{p[2] or 'full'}",
)
def trained_pair(request, spring: Spring, data: Dataset):
    torch_cls, jax_cls, batch = request.param
    cfg = torch_cls.Config(name="parity", dtype="float64", log_every=1, rollout_max_steps=3000)
    train = TrainSettings(steps=STEPS, batch_size=batch, lr=1e-3, weight_decay=1e-4)
    tm, jm = torch_cls(cfg, spring, "cpu"), jax_cls(cfg, spring, "cpu")
    t_hist = tm.fit(data, train, SEED, lambda *_: None).history
    j_hist = jm.fit(data, train, SEED, lambda *_: None).history
    return tm, jm, t_hist, j_hist


def test_loss_curves_agree(trained_pair):
    _, _, t_hist, j_hist = trained_pair
    assert t_hist["step"] == j_hist["step"] == list(range(1, STEPS + 1))
    for key in ("train_loss", "val_loss"):
        np.testing.assert_allclose(j_hist[key], t_hist[key], rtol=1e-4)
    # The curve must actually move, or agreement means nothing: the validation loss (the
    # whole validation set at every step, so no minibatch noise) falls by at least 1%,
    # a hundred times the agreement tolerance (the LNN at batch 100 moves slowest: ~2%).
    assert min(t_hist["val_loss"]) < 0.99 * t_hist["val_loss"][0]


def test_trained_weights_agree(trained_pair):
    tm, jm, _, _ = trained_pair
    t_state, j_state = torch_state(tm), jm.get_weights()
    assert set(t_state) == set(j_state)
    for key, value in t_state.items():
        np.testing.assert_allclose(j_state[key], value, rtol=1e-6, atol=1e-9, err_msg=key)


def test_same_weights_same_field_and_rollouts(trained_pair, spring: Spring, data: Dataset):
    tm, jm, _, _ = trained_pair
    jm.set_weights(torch_state(tm))  # exactly the same weights
    x = data.test.x
    np.testing.assert_allclose(jm.time_derivative(x), tm.time_derivative(x), rtol=1e-12, atol=1e-12)
    if jm.family.learned_energy:
        np.testing.assert_allclose(jm.energy(x), tm.energy(x), rtol=1e-10, atol=1e-10)
    ev = spring.evaluation(SEED)
    x0, t = ev.x0[:5], ev.t[:26]  # t in [0, 5], to keep the test short
    gave_up = []
    for model in (tm, jm):
        try:
            model.rollout(x0, t)
        except RolloutDiverged:
            gave_up.append(model.backend)
    # A stiff learned field (the LNN after 50 steps) makes both solvers give up, or none.
    assert gave_up in ([], ["torch", "jax"]), gave_up
    if gave_up:
        t = ev.t[:6]  # [0, 1]: the horizon both reach
    fwd_t, fwd_j = tm.rollout(x0, t), jm.rollout(x0, t)  # rtol = atol = 1e-9
    assert fwd_j.shape == fwd_t.shape
    np.testing.assert_allclose(fwd_j, fwd_t, rtol=0, atol=1e-6)
    t_back = np.ascontiguousarray(t[::-1])  # decreasing time: backward integration
    back_t = tm.rollout(fwd_t[:, -1], t_back)
    back_j = jm.rollout(fwd_j[:, -1], t_back)
    np.testing.assert_allclose(back_j, back_t, rtol=0, atol=1e-6)
    np.testing.assert_allclose(back_j[:, -1], x0, rtol=0, atol=1e-6)


@pytest.mark.parametrize("weight_decay", [0.0, 1e-4, 1e-2])
def test_optax_chain_is_torch_adam(weight_decay: float):
    """``add_decayed_weights`` + ``adam`` == ``torch.optim.Adam(weight_decay=...)``."""
    rng = np.random.default_rng(0)
    w0, target = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    w_t = torch.tensor(w0, requires_grad=True)
    opt_t = torch.optim.Adam([w_t], lr=1e-2, weight_decay=weight_decay)
    opt_j = optax.chain(optax.add_decayed_weights(weight_decay), optax.adam(1e-2))
    w_j = jnp.asarray(w0)
    state = opt_j.init(w_j)
    for _ in range(100):
        opt_t.zero_grad()
        loss = torch.sum(torch.tanh(w_t - torch.tensor(target)) ** 2)
        loss.backward()
        opt_t.step()
        # the same gradient formula, evaluated at the JAX iterate
        grad = 2 * np.tanh(np.asarray(w_j) - target) / np.cosh(np.asarray(w_j) - target) ** 2
        updates, state = opt_j.update(jnp.asarray(grad), state, w_j)
        w_j = optax.apply_updates(w_j, updates)
    np.testing.assert_allclose(np.asarray(w_j), w_t.detach().numpy(), rtol=1e-10, atol=1e-12)


def test_same_seed_same_autoencoder():
    from hnnbench_plugins.systems.pixel_pendulum import PixelPendulum, PixelPendulumConfig

    system = PixelPendulum(
        PixelPendulumConfig(
            name="pixel_pendulum", n_traj=10, n_frames=8, eval_n_traj=3, eval_n_points=6
        )
    )
    data = system.dataset(0)
    cfg = NeuralConfig(name="parity", hidden=16)
    tm, jm = HNNTorch(cfg, system, "cpu"), HNNJax(cfg, system, "cpu")
    t_state, j_state = built_weights_pixels(tm, data, 3), built_weights_pixels(jm, data, 3)
    for half in ("encoder", "decoder"):
        t_layers = sorted(k for k in t_state if k.startswith(f"autoencoder.{half}."))
        assert len(t_layers) == 2 * 4  # weight and bias of 4 layers
        for key in t_layers:
            assert t_state[key].dtype == np.float32
            np.testing.assert_array_equal(t_state[key], j_state[key])


def built_weights_pixels(model, data: Dataset, seed: int) -> dict[str, np.ndarray]:
    problem = model.view.problem(with_validation(data, seed))
    init = [model.initial_weights(seed, problem.train[0].shape[1])]
    train = TrainSettings(steps=1, batch_size=None, lr=1e-3, weight_decay=0.0)
    trainer = model._backend.trainer(
        model.family, model._impl, problem, init, train, model.layout()
    )
    (weights,) = model._backend.weights(trainer)
    return weights


@pytest.fixture(scope="module")
def double_pendulum():
    from hnnbench_plugins.systems.double_pendulum import DoublePendulum, DoublePendulumConfig

    system = DoublePendulum(DoublePendulumConfig(name="double_pendulum", n_traj=8))
    return system, system.dataset(SEED)


@pytest.mark.parametrize("embedding", ["cos_sin", "wrap"])
@pytest.mark.parametrize(("torch_cls", "jax_cls"), PAIRS)
def test_twins_agree_through_the_angle_embedding(torch_cls, jax_cls, embedding, double_pendulum):
    """On a system with angles (the double pendulum, angles beyond ±π), both backends
    embed them the same way: equal training curves and, from equal weights, equal
    fields and learned energies."""
    system, data = double_pendulum
    cfg = torch_cls.Config(
        name="parity", dtype="float64", log_every=1, hidden=32, angle_embedding=embedding
    )
    train = TrainSettings(steps=10, batch_size=None, lr=1e-3, weight_decay=1e-4)
    tm, jm = torch_cls(cfg, system, "cpu"), jax_cls(cfg, system, "cpu")
    assert any(spec.active for _, spec in tm.layout().nets)
    t_hist = tm.fit(data, train, SEED, lambda *_: None).history
    j_hist = jm.fit(data, train, SEED, lambda *_: None).history
    np.testing.assert_allclose(j_hist["train_loss"], t_hist["train_loss"], rtol=1e-8)
    jm.set_weights(tm.get_weights())
    x = data.test.x[:64]
    assert np.abs(x[:, :2]).max() > np.pi  # the embedding has something to do
    np.testing.assert_allclose(jm.time_derivative(x), tm.time_derivative(x), rtol=1e-10, atol=1e-10)
    if jm.family.learned_energy:
        np.testing.assert_allclose(jm.energy(x), tm.energy(x), rtol=1e-10, atol=1e-10)
