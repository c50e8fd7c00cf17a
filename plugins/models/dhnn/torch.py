"""The D-HNN in torch: ``ż = J ∇H + ∇D`` with the MLPs' closed-form input gradients."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP, symplectic


def field(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    return symplectic(nets["H"].input_gradient(z)) + nets["D"].input_gradient(z)


def energy(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    return nets["H"](z)[:, 0]
