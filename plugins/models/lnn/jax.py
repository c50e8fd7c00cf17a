"""The LNN in JAX: Euler-Lagrange accelerations with ``jax`` derivatives, per state."""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from hnnbench.neural.jax import Nets

Net = Callable[[jax.Array], jax.Array]


def _lagrangian(net: Net) -> Callable[[jax.Array, jax.Array], jax.Array]:
    """``L(q, q̇)`` of one state, a scalar."""
    return lambda q, qdot: net(jnp.concatenate([q, qdot]))[0]


def acceleration(net: Net, z: jax.Array) -> jax.Array:
    """``q̈`` ``(n,)`` of one velocity state ``z = (q, q̇)`` ``(2n,)``.

    One reverse pass gives ``∇_z L``; its forward-mode derivative along ``q̇`` alone
    (``n`` tangents) is the ``(2n, n)`` matrix ``∂(∇_z L)/∂q̇`` whose rows hold
    ``∂²L/∂q∂q̇`` (the transposed mixed block) and ``∂²L/∂q̇∂q̇``.
    """
    n = z.shape[0] // 2
    q, qdot = z[:n], z[n:]
    grad_z = jax.grad(lambda zz: net(zz)[0])

    def along_qdot(v: jax.Array) -> tuple[jax.Array, jax.Array]:
        g = grad_z(jnp.concatenate([q, v]))
        return g, g

    jac, g = jax.jacfwd(along_qdot, has_aux=True)(qdot)  # (2n, n), (2n,)
    mixed, hess = jac[:n].T, jac[n:]
    return jnp.linalg.solve(hess, g[:n] - mixed @ qdot)


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
