"""Networks of the JAX backend (equinox modules).

:class:`MLPNet` maps one input vector ``(d_in,)`` to ``(d_out,)``; ``jax.vmap`` it for a
batch. :class:`Nets` holds a model's networks by name (``nets["H"]``) and, for pixel
models, its autoencoder; it is a pytree whose static part is hashable, so a training
chunk can be compiled once per layout. Parameter names follow the torch backend's
(``"H.linears.0.weight"``), so weights move between backends unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Optional

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from hnnbench.neural._embedding import Layout, NetInput
from hnnbench.neural._init import AE_LAYERS
from hnnbench.neural._views import CC_WEIGHT, DYNAMICS_WEIGHT

__all__ = [
    "Autoencoder",
    "Dense",
    "MLPNet",
    "Nets",
    "nets_from_weights",
    "nets_to_weights",
    "pixel_objective",
    "pixel_objective_rows",
    "symplectic",
]

_ACTIVATIONS: dict[str, Callable[[jax.Array], jax.Array]] = {
    "tanh": jnp.tanh,
    "sigmoid": jax.nn.sigmoid,
    "softplus": jax.nn.softplus,
}


def symplectic(grad: jax.Array) -> jax.Array:
    """``(dH/dq, dH/dp) -> (dH/dp, -dH/dq)`` along the last axis: ``J ∇H``."""
    n = grad.shape[-1] // 2
    return jnp.concatenate([grad[..., n:], -grad[..., :n]], axis=-1)


class Dense(eqx.Module):
    """``y = W x (+ b)`` on one input vector; ``weight`` is ``(out, in)`` as in torch."""

    weight: jax.Array
    bias: Optional[jax.Array]

    def __call__(self, x: jax.Array) -> jax.Array:
        y = self.weight @ x
        return y if self.bias is None else y + self.bias


def embed(x: jax.Array, angles: tuple[int, ...], embedding: str) -> jax.Array:
    """The angle embedding (:mod:`hnnbench.neural._embedding`) of one input vector
    ``(w,)`` -> ``(features,)``."""
    if not angles or embedding == "none":
        return x
    cols = jnp.asarray(angles)
    theta = x[cols]
    if embedding == "wrap":
        return x.at[cols].set(
            theta - 2.0 * math.pi * jnp.floor((theta + math.pi) / (2.0 * math.pi))
        )
    return jnp.concatenate([x.at[cols].set(jnp.cos(theta)), jnp.sin(theta)])


class MLPNet(eqx.Module):
    """``len(linears)`` linear layers with an activation between them; the last has no
    bias. Maps one input vector ``(d_in,)`` to ``(d_out,)``; its ``angles`` (input
    columns) are embedded first (``embedding``: ``cos_sin``, ``wrap`` or ``none``)."""

    linears: tuple[Dense, ...]
    activation: str = eqx.field(static=True)
    angles: tuple[int, ...] = eqx.field(static=True, default=())
    embedding: str = eqx.field(static=True, default="none")

    def __call__(self, x: jax.Array) -> jax.Array:
        act = _ACTIVATIONS[self.activation]
        h = embed(x, self.angles, self.embedding)
        for layer in self.linears[:-1]:
            h = act(layer(h))
        return self.linears[-1](h)


class Autoencoder(eqx.Module):
    """The 2019 pixel autoencoder: ``d -> h -> (2 residual h) -> latent`` and its
    mirror, ReLU. ``encode`` / ``decode`` map one vector (``jax.vmap`` them)."""

    encoder: tuple[Dense, ...]
    decoder: tuple[Dense, ...]

    @staticmethod
    def _run(layers: tuple[Dense, ...], x: jax.Array) -> jax.Array:
        h = jax.nn.relu(layers[0](x))
        for layer in layers[1:-1]:
            h = h + jax.nn.relu(layer(h))
        return layers[-1](h)

    def encode(self, x: jax.Array) -> jax.Array:
        return self._run(self.encoder, x)

    def decode(self, z: jax.Array) -> jax.Array:
        return self._run(self.decoder, z)


class Nets(eqx.Module):
    """A model's networks by name, plus its autoencoder (pixel models)."""

    names: tuple[str, ...] = eqx.field(static=True)
    nets: tuple[MLPNet, ...]
    autoencoder: Optional[Autoencoder] = None

    def __getitem__(self, name: str) -> MLPNet:
        return self.nets[self.names.index(name)]


def nets_from_weights(
    weights: Mapping[str, Any], layout: Layout, layers: int, activation: str, dtype: Any
) -> Nets:
    """Build :class:`Nets` of ``layout``'s networks from flat weights
    (``"<net>.linears.<i>.weight"``, and ``"autoencoder.<half>.<i>.<weight|bias>"`` if
    present), cast to ``dtype``."""

    def array(key: str) -> jax.Array:  # cast by numpy, put as is: nothing compiled per shape
        return jax.device_put(np.asarray(weights[key], dtype=np.dtype(dtype)))

    def net(name: str, inputs: NetInput) -> MLPNet:
        linears = tuple(
            Dense(
                array(f"{name}.linears.{i}.weight"),
                None if i == layers - 1 else array(f"{name}.linears.{i}.bias"),
            )
            for i in range(layers)
        )
        if not inputs.active:
            return MLPNet(linears, activation)
        return MLPNet(linears, activation, tuple(inputs.angles), inputs.embedding)

    names = layout.names
    nets = tuple(net(name, inputs) for name, inputs in layout.nets)
    ae = None
    if "autoencoder.encoder.0.weight" in weights:

        def stack(half: str) -> tuple[Dense, ...]:
            return tuple(
                Dense(
                    array(f"autoencoder.{half}.{i}.weight"), array(f"autoencoder.{half}.{i}.bias")
                )
                for i in range(AE_LAYERS)
            )

        ae = Autoencoder(stack("encoder"), stack("decoder"))
    return Nets(names, nets, ae)


def nets_to_weights(nets: Nets, index: Optional[int] = None) -> dict[str, np.ndarray]:
    """Flat numpy weights of ``nets``; ``index`` selects one seed of stacked nets."""

    def get(a: jax.Array) -> np.ndarray:
        out = np.asarray(a)
        return out if index is None else out[index].copy()

    out: dict[str, np.ndarray] = {}
    for name, net in zip(nets.names, nets.nets, strict=True):
        for i, layer in enumerate(net.linears):
            out[f"{name}.linears.{i}.weight"] = get(layer.weight)
            if layer.bias is not None:
                out[f"{name}.linears.{i}.bias"] = get(layer.bias)
    if nets.autoencoder is not None:
        for half in ("encoder", "decoder"):
            for i, layer in enumerate(getattr(nets.autoencoder, half)):
                out[f"autoencoder.{half}.{i}.weight"] = get(layer.weight)
                assert layer.bias is not None
                out[f"autoencoder.{half}.{i}.bias"] = get(layer.bias)
    return out


def pixel_objective_rows(
    field: Callable[[Any, jax.Array], jax.Array], nets: Nets, x: jax.Array, x_next: jax.Array
) -> jax.Array:
    """:func:`pixel_objective` of each pair, ``(N,)`` (each term's mean over its row):
    their mean is the objective, up to rounding."""
    ae = nets.autoencoder
    assert ae is not None
    z, z_next = jax.vmap(ae.encode)(x), jax.vmap(ae.encode)(x_next)
    n = z.shape[1] // 2
    reconstruction = jnp.mean((jax.vmap(ae.decode)(z) - x) ** 2, axis=1)
    canonical = jnp.mean((z[:, n:] - (z_next[:, :n] - z[:, :n])) ** 2, axis=1)
    dynamics = jnp.mean((z_next - (z + field(nets, z))) ** 2, axis=1)
    return reconstruction + CC_WEIGHT * canonical + DYNAMICS_WEIGHT * dynamics


def pixel_objective(
    field: Callable[[Any, jax.Array], jax.Array], nets: Nets, x: jax.Array, x_next: jax.Array
) -> jax.Array:
    """The 2019 pixel loss on pairs of consecutive inputs ``x -> x_next`` (scalar):
    reconstruction + canonical coordinates + 0.1 x one Euler step (dt = 1) of ``field``."""
    ae = nets.autoencoder
    assert ae is not None
    z, z_next = jax.vmap(ae.encode)(x), jax.vmap(ae.encode)(x_next)
    n = z.shape[1] // 2
    reconstruction = jnp.mean((jax.vmap(ae.decode)(z) - x) ** 2)
    canonical = jnp.mean((z[:, n:] - (z_next[:, :n] - z[:, :n])) ** 2)
    dynamics = jnp.mean((z_next - (z + field(nets, z))) ** 2)
    return reconstruction + CC_WEIGHT * canonical + DYNAMICS_WEIGHT * dynamics
