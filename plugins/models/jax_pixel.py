"""Pixel support for the JAX models: an autoencoder with learned latent dynamics.

The JAX twin of :mod:`hnnbench_plugins.models.torch_pixel` (read its docstring for the
method): on a system with ``observation == "pixels"`` a :class:`PixelJaxModel` trains,
jointly, an MLP autoencoder ``D -> h -> h -> h -> 2n`` (two residual middle layers,
ReLU, orthogonal weights, zero biases) with a mirrored decoder, and the model's own latent
dynamics network (:class:`~.jax_base.MLPNet` and ``field``, as on state systems) on the
latents ``z = (z_q, z_p)``. The objective on consecutive inputs ``(x, x')``:

    L = mean((dec(z) - x)^2) + mean((z_p - (z'_q - z_q))^2) + 0.1 * mean((z' - (z + f(z)))^2)

Conventions (as the torch models): ``f`` is learned per frame (dt = 1);
``time_derivative(z) = f(z) / dt_frame`` and ``rollout(z0, t)`` integrates ``f`` over
``t / dt_frame`` (diffrax, float64, as on state systems), so both are in system time;
``energy`` (HNN) is the learned H on latents. ``encode (N, D) -> (N, 2n)``,
``decode (N, 2n) -> (N, D)``. ``loss(x, dxdt)`` is the full objective on
``(x, x + dt * dxdt)``.

Training is :mod:`~.jax_base`'s recipe: a jit-compiled :func:`jax.lax.scan` per log
interval (compiled once per shape and cached), host-drawn minibatch indices, Adam with
coupled weight decay (:func:`~.jax_base.adam_like_torch`). The logged test loss is taken
on at most 1024 evenly spaced test points. Weights are saved as an ``.npz`` (no pickle).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Optional

import numpy as np

from hnnbench.api import Dataset, FitResult, Progress, System, TrainSettings
from hnnbench.errors import ConfigError, RolloutDiverged
from hnnbench_plugins.models.jax_base import (
    Dense,
    Field,
    JaxModel,
    MLPNet,
    _compiled_chunk,
    adam_like_torch,
    eqx,
    jax,
    jnp,
    net_to_numpy,
    scan_steps,
)
from hnnbench_plugins.models.neural import (
    AE_LAYERS,
    NeuralConfig,
    autoencoder_init_arrays,
)

#: Weights of the objective's terms (the paper's).
CC_WEIGHT = 1.0
DYNAMICS_WEIGHT = 0.1
#: Rows per forward pass when evaluating whole splits (bounds memory).
CHUNK = 4096
#: The logged test loss is taken on this many evenly spaced test points.
LOG_TEST_POINTS = 1024
#: Format tag written into saved pixel weight files.
PIXEL_WEIGHTS_FORMAT = "hnnbench-jax-pixel/1"


class Autoencoder(eqx.Module):
    """MLP autoencoder ``d -> h -> (2 residual h) -> latent`` and its mirror, ReLU.
    ``encode`` / ``decode`` map one vector (``jax.vmap`` them for a batch)."""

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


def init_autoencoder(seed: int, d_obs: int, d_latent: int, hidden: int, dtype: Any
                     ) -> Autoencoder:
    """The seeded initial autoencoder (the same weights as the torch twin's)."""
    return autoencoder_from_numpy(autoencoder_init_arrays(seed, d_obs, d_latent, hidden),
                                  dtype)


def autoencoder_from_numpy(arrays: dict[str, np.ndarray], dtype: Any) -> Autoencoder:
    """Rebuild an :class:`Autoencoder` from ``{"encoder.0.weight": ..., ...}``."""

    def stack(prefix: str) -> tuple[Dense, ...]:
        return tuple(
            Dense(jnp.asarray(arrays[f"{prefix}.{i}.weight"], dtype=dtype),
                  jnp.asarray(arrays[f"{prefix}.{i}.bias"], dtype=dtype))
            for i in range(AE_LAYERS)
        )

    return Autoencoder(stack("encoder"), stack("decoder"))


def objective(
    field: Field, ae: Autoencoder, net: MLPNet, x: jax.Array, x_next: jax.Array
) -> jax.Array:
    """The paper's loss on pairs of consecutive inputs ``x -> x_next`` (scalar)."""
    z, z_next = jax.vmap(ae.encode)(x), jax.vmap(ae.encode)(x_next)
    n = z.shape[1] // 2
    reconstruction = jnp.mean((jax.vmap(ae.decode)(z) - x) ** 2)
    canonical = jnp.mean((z[:, n:] - (z_next[:, :n] - z[:, :n])) ** 2)
    dynamics = jnp.mean((z_next - (z + field(net, z))) ** 2)
    return reconstruction + CC_WEIGHT * canonical + DYNAMICS_WEIGHT * dynamics


@eqx.filter_jit
def _objective_jit(field: Field, ae: Autoencoder, net: MLPNet, x: jax.Array,
                   x_next: jax.Array) -> jax.Array:
    return objective(field, ae, net, x, x_next)


@eqx.filter_jit
def _encode(ae: Autoencoder, x: jax.Array) -> jax.Array:
    return jax.vmap(ae.encode)(x)


@eqx.filter_jit
def _decode(ae: Autoencoder, z: jax.Array) -> jax.Array:
    return jax.vmap(ae.decode)(z)


def _pixel_train_chunk(
    field: Field, static: Any, length: int, params: Any, opt_state: Any,
    idx: jax.Array | None, x: jax.Array, x_next: jax.Array, x_test: jax.Array,
    x_next_test: jax.Array, lr: jax.Array, weight_decay: jax.Array,
) -> tuple[Any, Any, jax.Array, jax.Array]:
    """One log interval of ``length`` steps under ``lax.scan`` (see
    :func:`~.jax_base._train_chunk`); ``params`` / ``static`` are the
    ``(autoencoder, dynamics net)`` pair's partitions."""
    optimizer = adam_like_torch(lr, weight_decay)

    def loss_fn(params: Any, xb: jax.Array, xnb: jax.Array) -> jax.Array:
        ae, net = eqx.combine(params, static)
        return objective(field, ae, net, xb, xnb)

    params, opt_state, losses = scan_steps(loss_fn, optimizer, params, opt_state, idx, x,
                                           x_next, length)
    return params, opt_state, losses, loss_fn(params, x_test, x_next_test)


_pixel_train_chunk_jit = jax.jit(_pixel_train_chunk, static_argnums=(0, 1, 2))


class PixelJaxModel(JaxModel):
    """A :class:`~.jax_base.JaxModel` that also runs on pixel systems (module
    docstring). On state systems every method is :class:`JaxModel`'s; on pixel systems
    ``self.net`` is the latent dynamics network, so the inherited ``time_derivative``,
    ``rollout`` and ``energy`` act on latents."""

    observations = ("state", "pixels")

    def __init__(self, cfg: NeuralConfig, system: System, device: str = "auto") -> None:
        super().__init__(cfg, system, device)
        self.pixels = system.observation == "pixels"
        self.autoencoder: Optional[Autoencoder] = None
        #: System time per frame step (the latent dynamics' unit of time).
        self.frame_dt = 1.0

    @property
    def latent_dim(self) -> int:
        return 2 * self.system.dof

    def _require_autoencoder(self) -> Autoencoder:
        if self.autoencoder is None:
            raise RuntimeError(f"{self.name}: call fit() or load() first")
        return self.autoencoder

    def _pairs(self, x: np.ndarray, dxdt: np.ndarray,
               extras: dict[str, np.ndarray]) -> tuple[jax.Array, jax.Array]:
        """``(x, x_next)``: ``extras["x_next"]`` if present, else ``x + dt * dxdt``."""
        x_next = extras.get("x_next")
        if x_next is None:
            x_next = np.asarray(x) + self.frame_dt * np.asarray(dxdt)
        return self._array(x), self._array(x_next)

    def _objective_mean(self, x: jax.Array, x_next: jax.Array) -> float:
        """The objective over a whole split, in chunks."""
        ae, net = self._require_autoencoder(), self._require_net()
        total = 0.0
        for start in range(0, int(x.shape[0]), CHUNK):
            xb, xnb = x[start : start + CHUNK], x_next[start : start + CHUNK]
            total += float(_objective_jit(self.field, ae, net, xb, xnb)) * int(xb.shape[0])
        return total / max(1, int(x.shape[0]))

    # -- training ---------------------------------------------------------------------
    def fit(
        self, data: Dataset, train: TrainSettings, seed: int, progress: Progress
    ) -> FitResult:
        if not self.pixels:
            return super().fit(data, train, seed, progress)
        if "dt" not in data.meta:
            raise ConfigError(f"{self.name}: pixel datasets must record meta['dt']")
        if self.initial_weights is not None:
            raise ConfigError(f"{self.name}: initial_weights are not supported on pixels")
        self.frame_dt = float(data.meta["dt"])
        x, x_next = self._pairs(data.train.x, data.train.dxdt, data.train.extras)
        test = data.test
        sub = np.unique(np.linspace(0, len(test) - 1, min(len(test), LOG_TEST_POINTS)).astype(int))
        x_test, x_next_test = self._pairs(
            test.x[sub], test.dxdt[sub], {k: v[sub] for k, v in test.extras.items()}
        )
        net = self.build(self.latent_dim, seed)
        ae = self._place(init_autoencoder(
            seed, int(x.shape[1]), self.latent_dim,
            self.cfg.hidden, self._dtype,
        ))
        params, static = eqx.partition((ae, net), eqx.is_inexact_array)
        opt_state = self._place(adam_like_torch(train.lr, train.weight_decay).init(params))
        hyper = (self._array(train.lr), self._array(train.weight_decay))

        lengths, indices = self._chunk_plan(train, int(x.shape[0]), seed)

        def keep(params: Any) -> None:
            ae, net = eqx.combine(params, static)
            self.autoencoder = ae
            self._set_net(net)

        compile_s = 0.0
        history: dict[str, list[float]] = {"step": [], "train_loss": [], "test_loss": []}
        step = 0
        idx = indices(lengths[0])
        for k, length in enumerate(lengths):
            args = (params, opt_state, idx, x, x_next, x_test, x_next_test, *hyper)
            compiled, seconds = _compiled_chunk(self.field, static, length, args,
                                                chunk=_pixel_train_chunk_jit)
            compile_s += seconds
            params, opt_state, losses, test_loss = compiled(*args)
            if k + 1 < len(lengths):
                idx = indices(lengths[k + 1])
            losses = np.asarray(losses)
            step += length
            train_loss, test_value = float(losses[-1]), float(test_loss)
            history["step"].append(step)
            history["train_loss"].append(train_loss)
            history["test_loss"].append(test_value)
            progress(step, {"train_loss": train_loss, "test_loss": test_value})
            if not (np.all(np.isfinite(losses)) and np.isfinite(test_value)):
                bad = np.flatnonzero(~np.isfinite(losses))
                at = step - length + 1 + int(bad[0]) if bad.size else step
                value = losses[bad[0]] if bad.size else test_value
                keep(params)
                raise RolloutDiverged(f"training loss became {value} at step {at}")
        self.timings["compile_s"] = self.timings.get("compile_s", 0.0) + compile_s
        keep(params)
        return FitResult(history=history, steps=train.steps)

    # -- inference --------------------------------------------------------------------
    def loss(self, x: np.ndarray, dxdt: np.ndarray) -> float:
        if not self.pixels:
            return super().loss(x, dxdt)
        return self._objective_mean(*self._pairs(x, dxdt, {}))

    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        out = super().time_derivative(x)
        return out / self.frame_dt if self.pixels else out

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        if self.pixels:
            t = np.asarray(t, dtype=np.float64) / self.frame_dt
        return super().rollout(x0, t, rtol=rtol, atol=atol)

    def _map(self, fn: Any, a: np.ndarray) -> np.ndarray:
        ae = self._require_autoencoder()
        out = [np.asarray(fn(ae, self._array(a[start : start + CHUNK])))
               for start in range(0, a.shape[0], CHUNK)]
        return np.concatenate(out).astype(np.float64) if out else np.zeros((0, 0))

    def encode(self, obs: np.ndarray) -> np.ndarray:
        if not self.pixels:
            return super().encode(obs)
        return self._map(_encode, np.asarray(obs))

    def decode(self, z: np.ndarray) -> Optional[np.ndarray]:
        if not self.pixels:
            return super().decode(z)
        return self._map(_decode, np.asarray(z))

    # -- persistence ------------------------------------------------------------------
    def save(self, path: Path) -> None:
        """Pixel models: an ``.npz`` of ``dynamics.*`` and ``autoencoder.*`` arrays
        plus a JSON header (with ``frame_dt``); no pickle."""
        if not self.pixels:
            return super().save(path)
        arrays = {f"dynamics.{k}": v for k, v in net_to_numpy(self._require_net()).items()}
        arrays.update({f"autoencoder.{k}": v
                       for k, v in net_to_numpy(self._require_autoencoder()).items()})
        meta = {"format": PIXEL_WEIGHTS_FORMAT, "model": type(self).__name__,
                "dtype": self.cfg.dtype, "activation": self.cfg.activation,
                "layers": self.cfg.layers, "hidden": self.cfg.hidden,
                "frame_dt": self.frame_dt}
        arrays["__meta__"] = np.array(json.dumps(meta))
        with open(path, "wb") as fh:  # a handle: numpy must not append ".npz"
            np.savez(fh, **arrays)

    def load(self, path: Path) -> None:
        if not self.pixels:
            return super().load(path)
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in npz.files}
        meta = json.loads(str(arrays.pop("__meta__", "{}")))
        if meta.get("format") != PIXEL_WEIGHTS_FORMAT:
            raise ValueError(f"{path} is not a {PIXEL_WEIGHTS_FORMAT} weight file")
        if meta.get("activation", self.cfg.activation) != self.cfg.activation:
            raise ValueError(
                f"{path} was trained with activation={meta['activation']}, but the model "
                f"is configured with activation={self.cfg.activation}"
            )

        def part(prefix: str) -> dict[str, np.ndarray]:
            return {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)}

        self.from_numpy_layers(part("dynamics."))
        self.autoencoder = self._place(
            autoencoder_from_numpy(part("autoencoder."), self._dtype)
        )
        self.frame_dt = float(meta.get("frame_dt", 1.0))

