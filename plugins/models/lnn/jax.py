"""The LNN in JAX: Euler-Lagrange accelerations with ``jax`` derivatives of the learned
Lagrangian (the network plus the family's declared kinetic term ``kinetic_prior ·
|q̇|²``, ``model.kinetic_prior``, default
:data:`~hnnbench_plugins.models.lnn.KINETIC_PRIOR`), per state."""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from hnnbench.neural.jax import Nets
from hnnbench_plugins.models.lnn import KINETIC_PRIOR

Net = Callable[[jax.Array], jax.Array]
#: A Lagrangian of one velocity state ``z = (q, q̇)`` ``(2n,)``: a scalar.
Lagrangian = Callable[[jax.Array], jax.Array]


def learned(net: Net, kinetic_prior: float = KINETIC_PRIOR) -> Lagrangian:
    """``L(z) = net(z) + kinetic_prior · |q̇|²`` of one state."""

    def lagrangian(z: jax.Array) -> jax.Array:
        qdot = z[z.shape[0] // 2 :]
        return net(z)[0] + kinetic_prior * jnp.sum(qdot * qdot)

    return lagrangian


def acceleration(lagrangian: Lagrangian, z: jax.Array) -> jax.Array:
    """``q̈`` ``(n,)`` of one velocity state ``z = (q, q̇)`` ``(2n,)``.

    One reverse pass gives ``∇_z L``; its forward-mode derivative along ``q̇`` alone
    (``n`` tangents) is the ``(2n, n)`` matrix ``∂(∇_z L)/∂q̇`` whose rows hold
    ``∂²L/∂q∂q̇`` (the transposed mixed block) and ``∂²L/∂q̇∂q̇``.
    """
    n = z.shape[0] // 2
    q, qdot = z[:n], z[n:]
    grad_z = jax.grad(lagrangian)

    def along_qdot(v: jax.Array) -> tuple[jax.Array, jax.Array]:
        g = grad_z(jnp.concatenate([q, v]))
        return g, g

    jac, g = jax.jacfwd(along_qdot, has_aux=True)(qdot)  # (2n, n), (2n,)
    mixed, hess = jac[:n].T, jac[n:]
    return jnp.linalg.solve(hess, g[:n] - mixed @ qdot)


def euler_lagrange(lagrangian: Lagrangian, z: jax.Array) -> jax.Array:
    """``(q̇, q̈)`` ``(N, 2n)`` of velocity states ``z`` ``(N, 2n)`` under ``lagrangian``."""
    n = z.shape[-1] // 2
    return jnp.concatenate(
        [z[:, n:], jax.vmap(lambda zi: acceleration(lagrangian, zi))(z)], axis=-1
    )


def field(
    nets: Nets | dict[str, Net], z: jax.Array, kinetic_prior: float = KINETIC_PRIOR
) -> jax.Array:
    return euler_lagrange(learned(nets["L"], kinetic_prior), z)


def energy(
    nets: Nets | dict[str, Net], z: jax.Array, kinetic_prior: float = KINETIC_PRIOR
) -> jax.Array:
    """``E = q̇ · ∂L/∂q̇ − L`` ``(N,)``."""
    lagrangian = learned(nets["L"], kinetic_prior)

    def one(zi: jax.Array) -> jax.Array:
        n = zi.shape[0] // 2
        return jax.grad(lagrangian)(zi)[n:] @ zi[n:] - lagrangian(zi)

    return jax.vmap(one)(z)
