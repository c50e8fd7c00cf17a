"""The D-HNN in torch: ``ż = J ∇H + s ∇D`` with the MLPs' closed-form input gradients
(``s``: the dissipation scale, ``model.dissipation_scale``, default 1)."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP, symplectic


def field(nets: dict[str, MLP], z: torch.Tensor, dissipation_scale: float = 1.0) -> torch.Tensor:
    return symplectic(nets["H"].input_gradient(z)) + dissipation_scale * nets["D"].input_gradient(z)


def energy(nets: dict[str, MLP], z: torch.Tensor, dissipation_scale: float = 1.0) -> torch.Tensor:
    return nets["H"](z)[:, 0]
