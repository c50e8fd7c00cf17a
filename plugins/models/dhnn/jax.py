"""The D-HNN in JAX: ``ż = J ∇H + ∇D`` with ``jax.grad``."""

from __future__ import annotations

import jax

from hnnbench.neural.jax import Nets, symplectic


def field(nets: Nets, z: jax.Array) -> jax.Array:
    grad_h = jax.vmap(jax.grad(lambda zi: nets["H"](zi)[0]))(z)
    grad_d = jax.vmap(jax.grad(lambda zi: nets["D"](zi)[0]))(z)
    return symplectic(grad_h) + grad_d


def energy(nets: Nets, z: jax.Array) -> jax.Array:
    return jax.vmap(nets["H"])(z)[:, 0]
