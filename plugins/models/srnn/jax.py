"""The SRNN in JAX: separable ``H = T(p) + V(q)``, leapfrog training loss."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from hnnbench.neural.jax import Nets


def _grads(nets: Nets):  # noqa: ANN202 - two gradient functions of one vector
    return (jax.grad(lambda p: nets["T"](p)[0]), jax.grad(lambda q: nets["V"](q)[0]))


def field(nets: Nets, z: jax.Array) -> jax.Array:
    n = z.shape[-1] // 2
    grad_t, grad_v = _grads(nets)
    return jnp.concatenate([jax.vmap(grad_t)(z[:, n:]), -jax.vmap(grad_v)(z[:, :n])], axis=-1)


def energy(nets: Nets, z: jax.Array) -> jax.Array:
    n = z.shape[-1] // 2
    return jax.vmap(nets["T"])(z[:, n:])[:, 0] + jax.vmap(nets["V"])(z[:, :n])[:, 0]


def step(nets: Nets, z: jax.Array, h: jax.Array) -> jax.Array:
    """One leapfrog step of size ``h`` from states ``z`` ``(M, 2n)`` (the map the SRNN
    trains through, and rolls out with under ``model.integrator=leapfrog``)."""
    n = z.shape[-1] // 2
    grad_t, grad_v = _grads(nets)
    q, p = z[:, :n], z[:, n:]
    p = p - 0.5 * h * jax.vmap(grad_v)(q)
    q = q + h * jax.vmap(grad_t)(p)
    p = p - 0.5 * h * jax.vmap(grad_v)(q)
    return jnp.concatenate([q, p], axis=-1)


def window_loss(nets: Nets, windows: jax.Array, dts: jax.Array, substeps: int = 1
                ) -> jax.Array:
    """Mean squared error of leapfrog predictions from each window's first state
    against its other states. ``windows`` ``(W, L, 2n)``, ``dts`` ``(W, L - 1)``."""

    def interval(z: jax.Array, dt: jax.Array) -> tuple[jax.Array, jax.Array]:
        h = (dt / substeps)[:, None]
        for _ in range(substeps):
            z = step(nets, z, h)
        return z, z

    _, predictions = jax.lax.scan(interval, windows[:, 0], jnp.swapaxes(dts, 0, 1))
    return jnp.mean((jnp.swapaxes(predictions, 0, 1) - windows[:, 1:]) ** 2)
