"""The D-HNN in JAX: ``ż = J ∇H + s ∇D`` with ``jax.grad`` (``s``: the dissipation
scale, ``model.dissipation_scale``, default 1)."""

from __future__ import annotations

import jax

from hnnbench.neural.jax import Nets, symplectic


def field(nets: Nets, z: jax.Array, dissipation_scale: float = 1.0) -> jax.Array:
    grad_h = jax.vmap(jax.grad(lambda zi: nets["H"](zi)[0]))(z)
    grad_d = jax.vmap(jax.grad(lambda zi: nets["D"](zi)[0]))(z)
    return symplectic(grad_h) + dissipation_scale * grad_d


def energy(nets: Nets, z: jax.Array, dissipation_scale: float = 1.0) -> jax.Array:
    return jax.vmap(nets["H"])(z)[:, 0]
