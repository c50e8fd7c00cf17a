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


def window_loss(nets: Nets, windows: jax.Array, dts: jax.Array, substeps: int = 1
                ) -> jax.Array:
    """Mean squared error of leapfrog predictions from each window's first state
    against its other states. ``windows`` ``(W, L, 2n)``, ``dts`` ``(W, L - 1)``."""
    n = windows.shape[-1] // 2
    grad_t, grad_v = _grads(nets)

    def leapfrog(z: jax.Array, h: jax.Array) -> jax.Array:
        q, p = z[:n], z[n:]
        p = p - 0.5 * h * grad_v(q)
        q = q + h * grad_t(p)
        p = p - 0.5 * h * grad_v(q)
        return jnp.concatenate([q, p])

    def one(window: jax.Array, steps: jax.Array) -> jax.Array:
        def interval(z: jax.Array, dt: jax.Array) -> tuple[jax.Array, jax.Array]:
            for _ in range(substeps):
                z = leapfrog(z, dt / substeps)
            return z, z

        _, predictions = jax.lax.scan(interval, window[0], steps)
        return jnp.mean((predictions - window[1:]) ** 2)

    return jnp.mean(jax.vmap(one)(windows, dts))
