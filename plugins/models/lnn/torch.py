"""The LNN in torch: Euler-Lagrange accelerations with ``torch.func`` derivatives of
the learned Lagrangian (the network plus the family's declared kinetic term,
:data:`~hnnbench_plugins.models.lnn.KINETIC_PRIOR`), per state (``vmap``)."""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch.func import grad, jacfwd, vmap

from hnnbench_plugins.models.lnn import KINETIC_PRIOR

Net = Callable[[torch.Tensor], torch.Tensor]
#: A Lagrangian of one velocity state ``z = (q, q̇)`` ``(2n,)``: a scalar.
Lagrangian = Callable[[torch.Tensor], torch.Tensor]


def learned(net: Net) -> Lagrangian:
    """``L(z) = net(z) + KINETIC_PRIOR · |q̇|²`` of one state."""
    def lagrangian(z: torch.Tensor) -> torch.Tensor:
        qdot = z[z.shape[0] // 2:]
        return net(z[None])[0, 0] + KINETIC_PRIOR * (qdot * qdot).sum()

    return lagrangian


def acceleration(lagrangian: Lagrangian, z: torch.Tensor) -> torch.Tensor:
    """``q̈`` ``(n,)`` of one velocity state ``z = (q, q̇)`` ``(2n,)``.

    One reverse pass gives ``∇_z L``; its forward-mode derivative along ``q̇`` alone
    (``n`` tangents) is the ``(2n, n)`` matrix ``∂(∇_z L)/∂q̇`` whose rows hold
    ``∂²L/∂q∂q̇`` (the transposed mixed block) and ``∂²L/∂q̇∂q̇``.
    """
    n = z.shape[0] // 2
    q, qdot = z[:n], z[n:]
    grad_z = grad(lagrangian)

    def along_qdot(v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        g = grad_z(torch.cat([q, v]))
        return g, g

    jac, g = jacfwd(along_qdot, has_aux=True)(qdot)  # (2n, n), (2n,)
    mixed, hess = jac[:n].T, jac[n:]  # [i, j] = ∂²L/∂q̇_i∂q_j ; ∂²L/∂q̇∂q̇
    # A singular Hessian gives NaN, as jnp.linalg.solve gives non-finite values: the
    # rollout then diverges (recorded `diverged`) instead of raising out of a metric.
    qddot, info = torch.linalg.solve_ex(hess, g[:n] - mixed @ qdot)
    return torch.where(info == 0, qddot, torch.full_like(qddot, torch.nan))


def euler_lagrange(lagrangian: Lagrangian, z: torch.Tensor) -> torch.Tensor:
    """``(q̇, q̈)`` ``(N, 2n)`` of velocity states ``z`` ``(N, 2n)`` under ``lagrangian``."""
    n = z.shape[-1] // 2
    return torch.cat([z[:, n:], vmap(lambda zi: acceleration(lagrangian, zi))(z)], dim=-1)


def field(nets: dict[str, Net], z: torch.Tensor) -> torch.Tensor:
    return euler_lagrange(learned(nets["L"]), z)


def energy(nets: dict[str, Net], z: torch.Tensor) -> torch.Tensor:
    """``E = q̇ · ∂L/∂q̇ − L`` ``(N,)``."""
    lagrangian = learned(nets["L"])

    def one(zi: torch.Tensor) -> torch.Tensor:
        n = zi.shape[0] // 2
        return grad(lagrangian)(zi)[n:] @ zi[n:] - lagrangian(zi)

    return vmap(one)(z)
