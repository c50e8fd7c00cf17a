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
    """``q̈`` ``(n,)`` of one velocity state ``z = (q, q̇)`` ``(2n,)``.

    One reverse pass gives ``∇_z L``; its forward-mode derivative along ``q̇`` alone
    (``n`` tangents) is the ``(2n, n)`` matrix ``∂(∇_z L)/∂q̇`` whose rows hold
    ``∂²L/∂q∂q̇`` (the transposed mixed block) and ``∂²L/∂q̇∂q̇``.
    """
    n = z.shape[0] // 2
    q, qdot = z[:n], z[n:]
    grad_z = grad(lambda zz: net(zz[None])[0, 0])

    def along_qdot(v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        g = grad_z(torch.cat([q, v]))
        return g, g

    jac, g = jacfwd(along_qdot, has_aux=True)(qdot)  # (2n, n), (2n,)
    mixed, hess = jac[:n].T, jac[n:]  # [i, j] = ∂²L/∂q̇_i∂q_j ; ∂²L/∂q̇∂q̇
    # A singular Hessian gives NaN, as jnp.linalg.solve gives non-finite values: the
    # rollout then diverges (recorded `diverged`) instead of raising out of a metric.
    qddot, info = torch.linalg.solve_ex(hess, g[:n] - mixed @ qdot)
    return torch.where(info == 0, qddot, torch.full_like(qddot, torch.nan))


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
