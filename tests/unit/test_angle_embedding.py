"""The periodic angle embedding (hnnbench/neural/_embedding.py): one map in numpy,
torch and JAX; the torch networks' closed-form gradients and Hessians through it equal
autograd's; networks are exactly 2π-periodic in each declared angle; the layouts and
weight shapes each family gets on an angle system."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hnnbench.neural import NeuralConfig
from hnnbench.neural._embedding import Layout, NetInput, embed, wrap
from hnnbench.neural._init import init_arrays

torch = pytest.importorskip("torch")

from hnnbench.neural.torch._nets import MLP, FrozenMLP  # noqa: E402

EMBEDDINGS = ("cos_sin", "wrap")


def make(
    spec: NetInput, d_out: int, cfg: NeuralConfig, seed: int = 0
) -> tuple[dict[str, np.ndarray], MLP, FrozenMLP]:
    arrays = {f"f.{k}": v for k, v in init_arrays(seed, spec.features, d_out, cfg).items()}
    params = {k: torch.tensor(v).requires_grad_() for k, v in arrays.items()}
    net = MLP.view(params, "f", cfg.layers, cfg.activation, spec)
    frozen = FrozenMLP.from_weights(
        arrays, "f", cfg.layers, cfg.activation, torch.float64, torch.device("cpu"), spec
    )
    return arrays, net, frozen


def states(n: int = 6, d: int = 4, seed: int = 1) -> np.ndarray:
    """States whose angles reach well beyond ±π (as the double pendulum's do)."""
    x = np.random.default_rng(seed).normal(size=(n, d))
    x[:, :2] *= 9.0
    return x


def test_the_numpy_reference():
    x = np.array([[3.0 * math.pi + 0.25, 1.5, -0.5, 2.0]])
    cos_sin = embed(NetInput(4, (0, 1), "cos_sin"), x)
    np.testing.assert_allclose(
        cos_sin, [[math.cos(x[0, 0]), math.cos(1.5), -0.5, 2.0, math.sin(x[0, 0]), math.sin(1.5)]]
    )
    np.testing.assert_allclose(embed(NetInput(4, (0,), "wrap"), x)[0, 0], 0.25 - math.pi)
    assert embed(NetInput(4, (0,), "none"), x) is not None
    np.testing.assert_array_equal(embed(NetInput(4, (0,), "none"), x), x)
    np.testing.assert_allclose(
        wrap(np.array([math.pi, -math.pi, 7.0])), [-math.pi, -math.pi, 7.0 - 2 * math.pi]
    )


@pytest.mark.parametrize("embedding", EMBEDDINGS)
def test_torch_embeds_as_the_reference(embedding):
    from hnnbench.neural.torch._nets import Periodic

    spec = NetInput(4, (0, 1), embedding)
    x = states()
    periodic = Periodic.of(spec)
    assert periodic is not None
    np.testing.assert_allclose(periodic.embed(torch.tensor(x)).numpy(), embed(spec, x), atol=1e-15)
    assert Periodic.of(NetInput(4, (), embedding)) is None
    assert Periodic.of(NetInput(4, (0,), "none")) is None


@pytest.mark.parametrize("embedding", EMBEDDINGS)
def test_jax_embeds_as_the_reference(embedding):
    pytest.importorskip("jax")
    import jax

    from hnnbench.neural.jax._nets import embed as jax_embed

    spec = NetInput(4, (0, 1), embedding)
    x = states()
    out = jax.vmap(lambda xi: jax_embed(xi, spec.angles, spec.embedding))(x)
    np.testing.assert_allclose(np.asarray(out), embed(spec, x), atol=1e-15)


@pytest.mark.parametrize("embedding", EMBEDDINGS)
@pytest.mark.parametrize("activation", ["tanh", "softplus"])
def test_closed_form_derivatives_through_the_embedding_are_autograds(embedding, activation):
    """Value, input gradient and every row block of the input Hessian (first_row 0 and
    2: the LNN's velocity rows) of the training view and of the frozen copy, through
    the embedding, equal torch.func's derivatives of the embedded network."""
    cfg = NeuralConfig(name="t", hidden=7, layers=3, activation=activation)
    spec = NetInput(4, (0, 1), embedding)
    _, net, frozen = make(spec, 1, cfg)
    x = torch.tensor(states())

    def scalar(xi: torch.Tensor) -> torch.Tensor:
        return net(xi[None])[0, 0]

    want_h = torch.func.vmap(torch.func.hessian(scalar))(x).detach()
    want_g = torch.func.vmap(torch.func.grad(scalar))(x).detach()
    for model in (net, frozen):
        np.testing.assert_allclose(model.input_gradient(x).detach(), want_g, rtol=1e-10, atol=1e-14)
        for first_row in (0, 2):
            value, grad, rows = model.input_hessian(x, first_row=first_row)
            np.testing.assert_allclose(value.detach(), net(x)[:, 0].detach(), rtol=1e-12)
            np.testing.assert_allclose(grad.detach(), want_g, rtol=1e-10, atol=1e-14)
            np.testing.assert_allclose(rows.detach(), want_h[:, first_row:], rtol=1e-9, atol=1e-13)


@pytest.mark.parametrize("embedding", EMBEDDINGS)
def test_networks_are_periodic_in_each_angle_and_only_there(embedding):
    cfg = NeuralConfig(name="t", hidden=16, layers=3)
    spec = NetInput(4, (0, 1), embedding)
    _, _, frozen = make(spec, 4, cfg)
    x = torch.tensor(states())
    for col in (0, 1):
        shifted = x.clone()
        shifted[:, col] += 2.0 * math.pi * 3
        np.testing.assert_allclose(frozen(shifted).numpy(), frozen(x).numpy(), atol=1e-10)
    shifted = x.clone()
    shifted[:, 2] += 2.0 * math.pi
    assert not np.allclose(frozen(shifted).numpy(), frozen(x).numpy(), atol=1e-6)
    # without the embedding, an angle shifted by 2π is another input
    _, _, plain = make(NetInput(4, (0, 1), "none"), 4, cfg)
    shifted = x.clone()
    shifted[:, 0] += 2.0 * math.pi
    assert not np.allclose(plain(shifted).numpy(), plain(x).numpy(), atol=1e-6)


def test_layouts_follow_what_each_network_reads():
    layout = Layout.build(4, {"T": (2, 1), "V": (2, 1)}, {"T": "p", "V": "q"}, (0, 1), "cos_sin")
    assert layout["T"] == NetInput(2, (), "cos_sin") and layout["T"].features == 2
    assert layout["V"] == NetInput(2, (0, 1), "cos_sin") and layout["V"].features == 4
    whole = Layout.build(4, {"H": (4, 1)}, {}, (1,), "wrap")
    assert whole["H"].features == 4 and whole["H"].angles == (1,)
    assert Layout.build(2, {"f": (2, 2)}, {}, (), "cos_sin")["f"].features == 2


@pytest.mark.parametrize(
    "model_name, system_name, shapes",
    [
        ("hnn_torch", "pendulum", {"H": (3, 1)}),
        ("srnn_jax", "double_pendulum", {"T": (2, 1), "V": (4, 1)}),
        ("lnn_jax", "double_pendulum", {"L": (6, 1)}),
        ("mlp_jax", "spring", {"f": (2, 2)}),
    ],
)
def test_each_family_gets_the_embedding_on_angle_systems(model_name, system_name, shapes):
    from hnnbench import _registry as registry

    system_cls = registry.SYSTEMS.get(system_name)
    system = system_cls(system_cls.Config(name=system_name))
    model_cls = registry.MODELS.get(model_name)
    model = model_cls(model_cls.Config(name=model_name), system, device="cpu")
    assert model.network_shapes() == shapes
    plain = model_cls(
        model_cls.Config(name=model_name, angle_embedding="none"), system, device="cpu"
    )
    assert {k: v[0] for k, v in plain.network_shapes().items()} == {
        k: (2 if k in ("T", "V") else 2 * system.dof) for k in shapes
    }
