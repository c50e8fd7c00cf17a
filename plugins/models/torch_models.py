"""The PyTorch baseline MLP and Hamiltonian neural network.

Both run on state and pixel systems; on pixels they learn their dynamics in the latent
space of an autoencoder (:mod:`hnnbench_plugins.models.torch_pixel`).
"""

from __future__ import annotations

import numpy as np

from hnnbench_plugins.models.torch_base import Network, torch
from hnnbench_plugins.models.torch_pixel import PixelTorchModel


def symplectic(grad: torch.Tensor) -> torch.Tensor:
    """``(dH/dq, dH/dp) -> (dH/dp, -dH/dq)`` for ``(N, 2n)`` gradients."""
    n = grad.shape[-1] // 2
    return torch.cat([grad[..., n:], -grad[..., :n]], dim=-1)


class MLPTorch(PixelTorchModel):
    """Baseline: an MLP that outputs dx/dt directly (PyTorch)."""

    version = "1"
    description = "Baseline MLP predicting dx/dt directly (PyTorch, paper architecture)"
    profiles = {}

    def field(self, net: Network, x: torch.Tensor) -> torch.Tensor:
        return net(x)


class HNNTorch(PixelTorchModel):
    """Hamiltonian neural network: an MLP outputs a scalar H; dx/dt is its symplectic
    gradient (dH/dp, -dH/dq) (PyTorch)."""

    version = "1"
    description = "Hamiltonian NN: scalar H, dynamics (dH/dp, -dH/dq) (PyTorch)"
    output_scalar = True

    def field(self, net: Network, x: torch.Tensor) -> torch.Tensor:
        return symplectic(net.input_gradient(x))

    def energy(self, x: np.ndarray) -> np.ndarray:
        net = self._float64_net()
        with torch.no_grad():
            return net(self._tensor(x, torch.float64))[:, 0].cpu().numpy()
