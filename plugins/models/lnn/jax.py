"""The LNN in JAX: Euler-Lagrange accelerations with ``jax`` derivatives, per state."""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from hnnbench.neural.jax.nets import Nets

Net = Callable[[jax.Array], jax.Array]


def _lagrangian(net: Net) -> Callable[[jax.Array, jax.Array], jax.Array]:
    """``L(q, q̇)`` of one state, a scalar."""
    return lambda q, qdot: net(jnp.concatenate([q, qdot]))[0]


def acceleration(net: Net, z: jax.Array) -> jax.Array:
    """``q̈`` ``(n,)`` of one velocity state ``z = (q, q̇)`` ``(2n,)``."""
    n = z.shape[0] // 2
    q, qdot = z[:n], z[n:]
    lag = _lagrangian(net)
    grad_q = jax.grad(lag, argnums=0)(q, qdot)
    hess = jax.hessian(lag, argnums=1)(q, qdot)  # ∂²L/∂q̇∂q̇
    mixed = jax.jacfwd(jax.grad(lag, argnums=1), argnums=0)(q, qdot)  # ∂²L/∂q̇_i∂q_j
    return jnp.linalg.solve(hess, grad_q - mixed @ qdot)


def field(nets: Nets | dict[str, Net], z: jax.Array) -> jax.Array:
    n = z.shape[-1] // 2
    net = nets["L"]
    return jnp.concatenate([z[:, n:], jax.vmap(lambda zi: acceleration(net, zi))(z)], axis=-1)


def energy(nets: Nets | dict[str, Net], z: jax.Array) -> jax.Array:
    net = nets["L"]

    def one(zi: jax.Array) -> jax.Array:
        n = zi.shape[0] // 2
        lag = _lagrangian(net)
        q, qdot = zi[:n], zi[n:]
        return jax.grad(lag, argnums=1)(q, qdot) @ qdot - lag(q, qdot)

    return jax.vmap(one)(z)
