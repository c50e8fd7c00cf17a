"""The frozen float64 network the torch models roll out with equals the trained module."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from hnnbench_plugins.models.neural import NeuralConfig  # noqa: E402
from hnnbench_plugins.models.torch_base import MLP, FrozenMLP  # noqa: E402


@pytest.mark.parametrize("activation", ["tanh", "sigmoid", "softplus"])
@pytest.mark.parametrize("layers", [2, 3, 4])
def test_forward_and_input_gradient_match_the_module(activation, layers):
    torch.manual_seed(layers)
    cfg = NeuralConfig(hidden=16, layers=layers, activation=activation)
    x = torch.tensor(np.random.default_rng(0).normal(size=(7, 4)))
    for d_out in (1, 4):
        net = MLP(4, d_out, cfg).double()
        frozen = FrozenMLP(net, torch.float64)
        np.testing.assert_allclose(frozen(x).numpy(), net(x).detach().numpy(), atol=1e-13)
    # the HNN's closed-form input gradient, against autograd
    net1 = MLP(4, 1, cfg).double()
    xg = x.clone().requires_grad_(True)
    (auto,) = torch.autograd.grad(net1(xg).sum(), xg)
    frozen1 = FrozenMLP(net1, torch.float64)
    np.testing.assert_allclose(frozen1.input_gradient(x).numpy(), auto.numpy(), atol=1e-13)
    np.testing.assert_allclose(net1.input_gradient(x).detach().numpy(), auto.numpy(),
                               atol=1e-13)


def test_is_a_copy_that_later_training_does_not_change():
    net = MLP(2, 2, NeuralConfig(hidden=8)).double()
    frozen = FrozenMLP(net, torch.float64)
    x = torch.ones((3, 2), dtype=torch.float64)
    before = frozen(x).clone()
    with torch.no_grad():
        for p in net.parameters():
            p.add_(1.0)
    assert torch.equal(frozen(x), before)
    assert not torch.equal(net(x).detach(), before)
