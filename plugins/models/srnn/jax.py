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


def _leap(
    grad_t, grad_v, q: jax.Array, p: jax.Array, force: jax.Array, h: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:  # noqa: ANN001 - gradient functions
    """One leapfrog step from ``(q, p)`` with ``force = ∇V(q)`` given; returns the new
    ``(q, p, ∇V(q))``: the last half-kick's force is the next step's first."""
    p = p - 0.5 * h * force
    q = q + h * jax.vmap(grad_t)(p)
    force = jax.vmap(grad_v)(q)
    return q, p - 0.5 * h * force, force


def step(nets: Nets, z: jax.Array, h: jax.Array) -> jax.Array:
    """One leapfrog step of size ``h`` from states ``z`` ``(M, 2n)`` (the map the SRNN
    trains through, and rolls out with under ``model.integrator=leapfrog``)."""
    n = z.shape[-1] // 2
    grad_t, grad_v = _grads(nets)
    q, p = z[:, :n], z[:, n:]
    q, p, _ = _leap(grad_t, grad_v, q, p, jax.vmap(grad_v)(q), h)
    return jnp.concatenate([q, p], axis=-1)


def window_loss(nets: Nets, windows: jax.Array, dts: jax.Array, substeps: int = 1) -> jax.Array:
    """Mean squared error of leapfrog predictions from each window's first state
    against its other states. ``windows`` ``(W, L, 2n)``, ``dts`` ``(W, L - 1)``.

    The steps of :func:`step`, chained, with each step's closing half-kick force
    ``∇V(q)`` reused by the next step's opening half-kick (the same value at the same
    ``q``): ``2k + 1`` evaluations of ``∇V`` and ``∇T`` for ``k`` steps instead of
    ``3k``. The scan over a window's few intervals is unrolled, so XLA optimises the
    whole window (and its gradient) as one graph: together about half the time of the
    rolled chain of steps (``benchmarks/srnn_window_loss.py``)."""
    n = windows.shape[-1] // 2
    grad_t, grad_v = _grads(nets)

    State = tuple[jax.Array, jax.Array, jax.Array]  # q, p, ∇V(q)

    def interval(carry: State, dt: jax.Array) -> tuple[State, jax.Array]:
        h = (dt / substeps)[:, None]
        q, p, force = carry
        for _ in range(substeps):
            q, p, force = _leap(grad_t, grad_v, q, p, force, h)
        return (q, p, force), jnp.concatenate([q, p], axis=-1)

    q, p = windows[:, 0, :n], windows[:, 0, n:]
    _, predictions = jax.lax.scan(
        interval, (q, p, jax.vmap(grad_v)(q)), jnp.swapaxes(dts, 0, 1), unroll=True
    )
    return jnp.mean((jnp.swapaxes(predictions, 0, 1) - windows[:, 1:]) ** 2)
