"""The HNN in JAX: ``ż = J ∇H`` with ``jax.grad``."""

from __future__ import annotations

import jax

from hnnbench.neural.jax import Nets, symplectic


def field(nets: Nets, z: jax.Array) -> jax.Array:
    grad = jax.vmap(jax.grad(lambda zi: nets["H"](zi)[0]))(z)
    return symplectic(grad)


def energy(nets: Nets, z: jax.Array) -> jax.Array:
    return jax.vmap(nets["H"])(z)[:, 0]
