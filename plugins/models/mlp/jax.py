"""The baseline MLP in JAX: ``ż = f(z)``."""

from __future__ import annotations

import jax

from hnnbench.neural.jax import Nets


def field(nets: Nets, z: jax.Array) -> jax.Array:
    return jax.vmap(nets["f"])(z)
