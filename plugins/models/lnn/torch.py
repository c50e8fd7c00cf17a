"""The LNN in torch: Euler-Lagrange accelerations from the network's value, input
gradient and input Hessian in closed form (:func:`hnnbench.neural.torch.input_hessian`:
one batched product per layer, no nested ``torch.func`` transforms), plus the family's
declared kinetic term ``kinetic_prior · |q̇|²`` (``model.kinetic_prior``, default
:data:`~hnnbench_plugins.models.lnn.KINETIC_PRIOR`).
"""

from __future__ import annotations

from typing import Protocol

import torch

from hnnbench_plugins.models.lnn import KINETIC_PRIOR


class Net(Protocol):
    def input_hessian(
        self, x: torch.Tensor, first_row: int = 0
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(value (N,), gradient (N, d), Hessian rows first_row: (N, d - first_row, d))``."""
        ...


def _lagrangian(
    net: Net, z: torch.Tensor, kinetic_prior: float
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``L = net + kinetic_prior · |q̇|²`` at velocity states ``z = (q, q̇)`` ``(N, 2n)``:
    its value ``(N,)``, gradient ``(N, 2n)`` and velocity rows of the Hessian
    ``∂²L/∂q̇∂z`` ``(N, n, 2n)``."""
    n = z.shape[-1] // 2
    qdot = z[:, n:]
    value, grad, rows = net.input_hessian(z, first_row=n)
    value = value + kinetic_prior * (qdot * qdot).sum(-1)
    grad = torch.cat([grad[:, :n], grad[:, n:] + 2.0 * kinetic_prior * qdot], dim=-1)
    eye = torch.eye(n, dtype=z.dtype, device=z.device)
    rows = torch.cat([rows[:, :, :n], rows[:, :, n:] + 2.0 * kinetic_prior * eye], dim=-1)
    return value, grad, rows


def field(
    nets: dict[str, Net], z: torch.Tensor, kinetic_prior: float = KINETIC_PRIOR
) -> torch.Tensor:
    """``(q̇, q̈)`` ``(N, 2n)`` with ``q̈ = (∂²L/∂q̇²)⁻¹ (∂L/∂q − ∂²L/∂q̇∂q q̇)``."""
    n = z.shape[-1] // 2
    qdot = z[:, n:]
    _, grad, rows = _lagrangian(nets["L"], z, kinetic_prior)
    rhs = grad[:, :n] - (rows[:, :, :n] @ qdot[:, :, None])[:, :, 0]
    # A singular Hessian gives NaN, as jnp.linalg.solve gives non-finite values: the
    # rollout then diverges (recorded `diverged`) instead of raising out of a metric.
    qddot, info = torch.linalg.solve_ex(rows[:, :, n:], rhs)
    qddot = torch.where((info == 0)[:, None], qddot, torch.full_like(qddot, torch.nan))
    return torch.cat([qdot, qddot], dim=-1)


def energy(
    nets: dict[str, Net], z: torch.Tensor, kinetic_prior: float = KINETIC_PRIOR
) -> torch.Tensor:
    """``E = q̇ · ∂L/∂q̇ − L`` ``(N,)``."""
    n = z.shape[-1] // 2
    value, grad, _ = _lagrangian(nets["L"], z, kinetic_prior)
    return (grad[:, n:] * z[:, n:]).sum(-1) - value
