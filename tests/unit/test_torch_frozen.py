"""The frozen float64 network the torch models roll out with equals the training
network (the same weights through :class:`MLP`'s ops)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from hnnbench.neural import NeuralConfig  # noqa: E402
from hnnbench.neural._init import init_arrays  # noqa: E402
from hnnbench.neural.torch._nets import MLP, FrozenMLP  # noqa: E402


def make(
    d_in: int, d_out: int, cfg: NeuralConfig, seed: int = 0
) -> tuple[dict[str, torch.Tensor], MLP, FrozenMLP]:
    """Training parameters (float64, requiring grad), their MLP view and a frozen copy."""
    arrays = {f"f.{k}": v for k, v in init_arrays(seed, d_in, d_out, cfg).items()}
    params = {k: torch.tensor(v).requires_grad_() for k, v in arrays.items()}
    net = MLP.view(params, "f", cfg.layers, cfg.activation)
    numpy_weights = {k: v.detach().numpy() for k, v in params.items()}
    frozen = FrozenMLP.from_weights(
        numpy_weights, "f", cfg.layers, cfg.activation, torch.float64, torch.device("cpu")
    )
    return params, net, frozen


@pytest.mark.parametrize("activation", ["tanh", "sigmoid", "softplus"])
@pytest.mark.parametrize("layers", [2, 3, 4])
def test_forward_and_input_gradient_match_the_module(activation, layers):
    cfg = NeuralConfig(hidden=16, layers=layers, activation=activation)
    x = torch.tensor(np.random.default_rng(0).normal(size=(7, 4)))
    for d_out in (1, 4):
        _, net, frozen = make(4, d_out, cfg, seed=layers)
        np.testing.assert_allclose(frozen(x).numpy(), net(x).detach().numpy(), atol=1e-13)
    # the HNN's closed-form input gradient, against autograd
    _, net1, frozen1 = make(4, 1, cfg, seed=layers)
    xg = x.clone().requires_grad_(True)
    (auto,) = torch.autograd.grad(net1(xg).sum(), xg)
    np.testing.assert_allclose(frozen1.input_gradient(x).numpy(), auto.numpy(), atol=1e-13)
    np.testing.assert_allclose(net1.input_gradient(x).detach().numpy(), auto.numpy(), atol=1e-13)


def test_is_a_copy_that_later_training_does_not_change():
    params, net, frozen = make(2, 2, NeuralConfig(hidden=8))
    x = torch.ones((3, 2), dtype=torch.float64)
    before = frozen(x).clone()
    with torch.no_grad():
        for p in params.values():
            p.add_(1.0)
    assert torch.equal(frozen(x), before)
    assert not torch.equal(net(x).detach(), before)


@pytest.mark.parametrize("activation", ["tanh", "sigmoid", "softplus"])
@pytest.mark.parametrize("layers", [2, 3, 4])
def test_the_closed_form_input_hessian_is_autograds(activation, layers):
    """``input_hessian`` (value, gradient, Hessian rows; the torch LNN's derivatives) of
    the training view and of the frozen copy equal torch.func's, in float64."""
    cfg = NeuralConfig(name="t", hidden=7, layers=layers, activation=activation)
    params, net, frozen = make(4, 1, cfg)
    x = torch.tensor(np.random.default_rng(1).normal(size=(5, 4)))

    def scalar(xi: torch.Tensor) -> torch.Tensor:
        return net(xi[None])[0, 0]

    want_h = torch.func.vmap(torch.func.hessian(scalar))(x)
    want_g = torch.func.vmap(torch.func.grad(scalar))(x)
    for model in (net, frozen):
        value, grad, rows = model.input_hessian(x, first_row=2)
        np.testing.assert_allclose(value.detach(), net(x)[:, 0].detach(), rtol=1e-12)
        np.testing.assert_allclose(grad.detach(), want_g.detach(), rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(rows.detach(), want_h[:, 2:].detach(), rtol=1e-9, atol=1e-13)
    # training differentiates through it: a parameter gradient of the Hessian exists
    _, _, rows = net.input_hessian(x)
    rows.sum().backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in params.values())
