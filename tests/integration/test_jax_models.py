"""Unit tests of the JAX models (MLPJax, HNNJax): fast, small networks, CPU."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("equinox")
pytest.importorskip("optax")
pytest.importorskip("diffrax")

from hnnbench._contracts.errors import ConfigError, RolloutDiverged  # noqa: E402
from hnnbench._contracts.plugin import Dataset, TrainSettings  # noqa: E402
from hnnbench.neural import NeuralConfig
from hnnbench.neural._init import mlp_shapes  # noqa: E402
from hnnbench.neural.jax import _gpus  # noqa: E402
from hnnbench_plugins.models.hnn import HNNJax  # noqa: E402
from hnnbench_plugins.models.mlp import MLPJax  # noqa: E402
from hnnbench_plugins.systems.spring import Spring, SpringConfig  # noqa: E402

MODELS = [MLPJax, HNNJax]


@pytest.fixture(scope="module")
def spring() -> Spring:
    return Spring(
        SpringConfig(
            name="spring", n_traj=8, n_points=10, eval_n_traj=3, eval_n_points=20, eval_t_end=3.0
        )
    )


@pytest.fixture(scope="module")
def data(spring: Spring) -> Dataset:
    return spring.dataset(0)


def make(cls: type, spring: Spring, device: str = "cpu", **overrides: object):
    cfg = NeuralConfig(name=cls.__name__.lower(), hidden=32, log_every=5)
    return cls(dataclasses.replace(cfg, **overrides), spring, device)


def settings(steps: int = 20, batch_size: int | None = None) -> TrainSettings:
    return TrainSettings(steps=steps, batch_size=batch_size, lr=1e-3, weight_decay=1e-4)


def fit(model, data: Dataset, steps: int = 20, batch_size: int | None = None, seed: int = 0):
    calls: list[tuple[int, dict]] = []
    result = model.fit(
        data,
        settings(steps, batch_size),
        seed,
        lambda step, losses: calls.append((step, dict(losses))),
    )
    return result, calls


@pytest.fixture(scope="module", params=MODELS, ids=lambda c: c.__name__)
def trained(request, spring: Spring, data: Dataset):
    model = make(request.param, spring)
    fit(model, data)
    return model


# --------------------------------------------------------------------------- training


@pytest.mark.parametrize("cls", MODELS, ids=lambda c: c.__name__)
def test_fit_history_progress_and_timings(cls, spring, data):
    model = make(cls, spring)
    result, calls = fit(model, data, steps=12)  # log_every=5: intervals of 5, 5, 2
    assert result.steps == 12
    assert result.history["step"] == [5, 10, 12]
    assert set(result.history) == {"step", "train_loss", "val_loss"}
    assert all(len(v) == 3 for v in result.history.values())
    assert [step for step, _ in calls] == [5, 10, 12]
    assert set(calls[0][1]) == {"train_loss", "val_loss"}
    assert np.all(np.isfinite(result.history["train_loss"]))
    assert model.timings["compile_s"] >= 0.0
    assert model.device == "cpu"


def test_compile_time_recorded_and_cached(spring, data):
    first = make(MLPJax, spring, hidden=24)  # a layout no other test compiles
    fit(first, data, steps=5)
    assert first.timings["compile_s"] > 0.0
    second = make(MLPJax, spring, hidden=24)
    result, _ = fit(second, data, steps=5, seed=1)  # same shapes: reuses the executable
    assert second.timings["compile_s"] == 0.0
    assert np.all(np.isfinite(result.history["train_loss"]))


def test_training_dtype_and_float64_inference(trained, data):
    leaves = trained.get_weights()
    assert all(v.dtype == np.float32 for v in leaves.values())  # cfg.dtype default
    out = trained.time_derivative(data.test.x)
    assert out.shape == data.test.x.shape and out.dtype == np.float64


@pytest.mark.parametrize("n", [0, 1, 1023, 1024, 1025, 2100])
def test_field_and_energy_in_blocks_of_rows_equal_one_call(trained, n):
    """Inference runs rows in blocks of ROWS (the last padded by repeating its last row):
    at every block edge it returns what one call on all rows returns."""
    import jax.numpy as jnp

    from hnnbench.neural.jax import ROWS, _apply

    assert ROWS == 1024
    z = np.random.default_rng(n).normal(size=(n, 2))
    infer = trained._infer()
    for name in ("field", "energy"):
        fn = getattr(trained._impl, name, None)
        if fn is None:
            continue
        got = getattr(infer, name)(z)
        want = np.asarray(_apply(fn, infer.nets64, jnp.asarray(z, dtype=jnp.float64)))
        assert got.shape == want.shape and got.dtype == np.float64
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("batch_size", [None, 16], ids=["full", "minibatch"])
@pytest.mark.parametrize("cls", MODELS, ids=lambda c: c.__name__)
def test_same_seed_same_losses(cls, spring, data, batch_size):
    runs = [
        fit(make(cls, spring), data, steps=10, batch_size=batch_size, seed=seed)[0]
        for seed in (3, 3, 4)
    ]
    assert runs[0].history == runs[1].history
    assert runs[0].history["train_loss"] != runs[2].history["train_loss"]


def test_log_every_step(spring, data):
    result, calls = fit(make(HNNJax, spring, log_every=1), data, steps=4)
    assert result.history["step"] == [1, 2, 3, 4]
    assert len(calls) == 4


def test_nonfinite_training_loss_is_reported_as_diverged(spring, data):
    """Training that diverges returns its result with the reason set (the job records
    ``diverged``), never raises."""
    x = data.train.x.copy()
    x[0, 0] = np.nan
    bad = Dataset(train=dataclasses.replace(data.train, x=x), test=data.test)
    result, _ = fit(make(MLPJax, spring), bad, steps=10)
    assert result.diverged == "training loss became nan at step 1"
    assert len(result.history["step"]) == 1  # training stopped at the first chunk


def test_minibatch_larger_than_data_is_full_batch(spring, data):
    full, _ = fit(make(MLPJax, spring), data, steps=5, batch_size=None)
    big, _ = fit(make(MLPJax, spring), data, steps=5, batch_size=10 * len(data.train))
    assert full.history == big.history


# --------------------------------------------------------------------------- fields


def test_shapes(trained, data, spring):
    x = data.test.x[:7]
    assert trained.time_derivative(x).shape == (7, 2)
    ev = spring.evaluation(0)
    ys = trained.rollout(ev.x0, ev.t)
    assert ys.shape == (len(ev.x0), len(ev.t), 2) and ys.dtype == np.float64
    np.testing.assert_allclose(ys[:, 0], ev.x0, atol=1e-12)
    energy = trained.energy(x)
    if isinstance(trained, HNNJax):
        assert energy.shape == (7,) and energy.dtype == np.float64
    else:
        assert energy is None


def test_hnn_field_is_symplectic_gradient_of_energy(spring, data):
    model = make(HNNJax, spring)
    fit(model, data, steps=5)
    x = data.test.x[:5]
    h = 1e-6
    grad = np.empty_like(x)
    for j in range(x.shape[1]):
        e = np.zeros(x.shape[1])
        e[j] = h
        grad[:, j] = (model.energy(x + e) - model.energy(x - e)) / (2 * h)
    expected = np.concatenate([grad[:, 1:], -grad[:, :1]], axis=1)  # (dH/dp, -dH/dq)
    np.testing.assert_allclose(model.time_derivative(x), expected, rtol=1e-6, atol=1e-8)


def test_backward_rollout_returns_to_start(trained, spring):
    ev = spring.evaluation(0)
    t = ev.t  # the shapes of test_shapes: reuses the compiled solver
    fwd = trained.rollout(ev.x0, t, rtol=1e-10, atol=1e-10)
    back = trained.rollout(fwd[:, -1], t[::-1], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(back[:, 0], fwd[:, -1], atol=1e-12)
    np.testing.assert_allclose(back[:, ::-1], fwd, atol=1e-6)  # same path, reversed


def test_rollout_tiny_step_budget_raises(spring, data):
    model = make(HNNJax, spring, rollout_max_steps=3)
    fit(model, data, steps=5)
    ev = spring.evaluation(0)
    with pytest.raises(RolloutDiverged, match="maximum number of solver steps"):
        model.rollout(ev.x0, ev.t)


# --------------------------------------------------------------------------- weights


def test_save_load_round_trip(trained, spring, data, tmp_path: Path):
    from safetensors.numpy import load_file

    path = tmp_path / "weights.bin"  # any name: no suffix may be appended
    trained.save(path)
    assert path.exists() and [p.name for p in tmp_path.iterdir()] == ["weights.bin"]
    files = set(load_file(str(path)))  # readable without pickle
    net = next(iter(trained.network_shapes()))
    assert {f"{net}.linears.0.weight", f"{net}.linears.0.bias", f"{net}.linears.2.weight"} <= files
    assert f"{net}.linears.2.bias" not in files  # last layer has no bias
    fresh = make(type(trained), spring)
    fresh.load(path)
    np.testing.assert_array_equal(
        fresh.time_derivative(data.test.x), trained.time_derivative(data.test.x)
    )


def test_load_rejects_other_layout(trained, spring, tmp_path: Path):
    path = tmp_path / "weights.npz"
    trained.save(path)
    with pytest.raises(ValueError, match="shape"):
        make(type(trained), spring, hidden=16).load(path)


def test_weights_of_the_other_model_are_rejected(trained, spring):
    other = HNNJax if isinstance(trained, MLPJax) else MLPJax
    with pytest.raises(ValueError, match="do not match"):
        make(other, spring).set_weights(trained.get_weights())


def test_numpy_layers_round_trip(trained, spring, data):
    ((net, (d_in, d_out)),) = trained.network_shapes().items()
    layers = trained.get_weights()  # "<net>.linears.<i>.weight", as the torch backend
    expected = {f"{net}.{k}": v for k, v in mlp_shapes(d_in, d_out, trained.cfg).items()}
    assert {k: v.shape for k, v in layers.items()} == expected
    other = make(type(trained), spring)
    other.set_weights(trained.get_weights())
    np.testing.assert_array_equal(
        other.time_derivative(data.test.x), trained.time_derivative(data.test.x)
    )


def test_initial_weights_start_fit(spring, data):
    a = make(MLPJax, spring)
    fit(a, data, steps=5, seed=1)
    b = make(MLPJax, spring)
    b.warm_start = a.get_weights()
    c = make(MLPJax, spring)
    c.warm_start = a.get_weights()
    rb, _ = fit(b, data, steps=5, seed=2)
    rc, _ = fit(c, data, steps=5, seed=7)  # the seed no longer matters (full batch)
    assert rb.history == rc.history


# --------------------------------------------------------------------------- device


def test_cuda_without_gpu_is_one_line_config_error(spring):
    # Asked here, not in a skipif: that would start JAX's backends at collection, in
    # an unpinned pytest process, and later in-process runs would then differ in the
    # last bits from the CLI's (tests/integration/test_api.py).
    if _gpus():
        pytest.skip("a GPU is present")
    with pytest.raises(ConfigError) as err:
        make(MLPJax, spring, device="cuda")
    assert "\n" not in str(err.value) and "device=cuda" in str(err.value)


def test_auto_and_invalid_device(spring):
    assert make(MLPJax, spring, device="auto").device == ("cuda:0" if _gpus() else "cpu")
    with pytest.raises(ConfigError, match="expected auto, cpu, cuda"):
        make(MLPJax, spring, device="tpu")


def test_missing_jax_gives_install_hint():
    code = (
        "import sys; sys.modules['jax'] = None\n"
        "from hnnbench._contracts.errors import BackendMissingError\n"
        "from hnnbench.neural import NeuralConfig\n"
        "from hnnbench_plugins.models.mlp import MLPJax\n"
        "from hnnbench_plugins.systems.spring import Spring, SpringConfig\n"
        "print(MLPJax.requirements_missing())\n"
        "try:\n"
        "    MLPJax(NeuralConfig(name='mlp_jax'), Spring(SpringConfig(name='spring')), 'cpu')\n"
        "except BackendMissingError as err:\n"
        "    print(err)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    lines = out.strip().splitlines()
    assert len(lines) == 2
    assert all("pip install 'hnnbench[jax]'" in line for line in lines)
