"""The HNN in torch: ``ż = J ∇H`` with the closed-form input gradient of the MLP."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP, symplectic


def field(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    return symplectic(nets["H"].input_gradient(z))


def energy(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    return nets["H"](z)[:, 0]
