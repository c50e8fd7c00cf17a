"""The second-order MLP in JAX: ``(q, q̇)' = (q̇, g(q, q̇))``."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from hnnbench.neural.jax import Nets


def field(nets: Nets, z: jax.Array) -> jax.Array:
    n = z.shape[-1] // 2
    return jnp.concatenate([z[:, n:], jax.vmap(nets["g"])(z)], axis=-1)
