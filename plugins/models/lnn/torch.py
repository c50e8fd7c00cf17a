"""The LNN in torch: Euler-Lagrange accelerations with ``torch.func`` derivatives of
the network, per state (``vmap``)."""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch.func import grad, jacfwd, vmap

Net = Callable[[torch.Tensor], torch.Tensor]


def _lagrangian(net: Net, n: int) -> Callable[[torch.Tensor, torch.Tensor], torch.Tensor]:
    """``L(q, q̇)`` of one state, a scalar."""
    return lambda q, qdot: net(torch.cat([q, qdot])[None])[0, 0]


def acceleration(net: Net, z: torch.Tensor) -> torch.Tensor:
    """``q̈`` ``(n,)`` of one velocity state ``z = (q, q̇)`` ``(2n,)``."""
    n = z.shape[0] // 2
    q, qdot = z[:n], z[n:]
    lag = _lagrangian(net, n)
    grad_q = grad(lag, argnums=0)(q, qdot)
    hess = jacfwd(grad(lag, argnums=1), argnums=1)(q, qdot)  # ∂²L/∂q̇∂q̇
    mixed = jacfwd(grad(lag, argnums=1), argnums=0)(q, qdot)  # [i, j] = ∂²L/∂q̇_i∂q_j
    return torch.linalg.solve(hess, grad_q - mixed @ qdot)


def field(nets: dict[str, Net], z: torch.Tensor) -> torch.Tensor:
    n = z.shape[-1] // 2
    net = nets["L"]
    return torch.cat([z[:, n:], vmap(lambda zi: acceleration(net, zi))(z)], dim=-1)


def energy(nets: dict[str, Net], z: torch.Tensor) -> torch.Tensor:
    net = nets["L"]

    def one(zi: torch.Tensor) -> torch.Tensor:
        n = zi.shape[0] // 2
        lag = _lagrangian(net, n)
        q, qdot = zi[:n], zi[n:]
        return grad(lag, argnums=1)(q, qdot) @ qdot - lag(q, qdot)

    return vmap(one)(z)
