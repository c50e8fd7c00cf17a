"""The JAX baseline MLP and Hamiltonian neural network (twins of the PyTorch models).

Both run on state and pixel systems; on pixels they learn their dynamics in the latent
space of an autoencoder (:mod:`hnnbench_plugins.models.jax_pixel`).
"""

from __future__ import annotations

import numpy as np

from hnnbench_plugins.models.jax_base import (
    MLPNet,
    _apply,
    jax,
    jnp,
    symplectic,
)
from hnnbench_plugins.models.jax_pixel import PixelJaxModel


def mlp_field(net: MLPNet, x: jax.Array) -> jax.Array:
    """The network's output is ``dx/dt``."""
    return jax.vmap(net)(x)


def hamiltonian(net: MLPNet, x: jax.Array) -> jax.Array:
    """The learned scalar ``H`` ``(N,)`` of a batch ``x`` ``(N, 2n)``."""
    return jax.vmap(net)(x)[:, 0]


def hnn_field(net: MLPNet, x: jax.Array) -> jax.Array:
    """``dx/dt = (dH/dp, -dH/dq)``, the symplectic gradient of the learned ``H``."""
    grad = jax.vmap(jax.grad(lambda xi: net(xi)[0]))(x)
    return symplectic(grad)


class MLPJax(PixelJaxModel):
    """Baseline: an MLP that outputs dx/dt directly (JAX: equinox + optax + diffrax)."""

    version = "1"
    description = "Baseline MLP predicting dx/dt directly (JAX, paper architecture)"
    profiles = {}
    field = staticmethod(mlp_field)


class HNNJax(PixelJaxModel):
    """Hamiltonian neural network: an MLP outputs a scalar H; dx/dt is its symplectic
    gradient (dH/dp, -dH/dq), taken with ``jax.grad`` (JAX)."""

    version = "1"
    description = "Hamiltonian NN: scalar H, dynamics (dH/dp, -dH/dq) (JAX)"
    profiles = {}
    output_scalar = True
    field = staticmethod(hnn_field)

    def energy(self, x: np.ndarray) -> np.ndarray:
        out = _apply(hamiltonian, self._float64_net(), self._array(x, jnp.float64))
        return np.asarray(out, dtype=np.float64)
