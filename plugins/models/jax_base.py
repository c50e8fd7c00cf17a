"""Shared machinery of the JAX models: device, network, training loop, float64 rollouts.

The JAX twins of :mod:`hnnbench_plugins.models.torch_base`: same architecture (an MLP of
``cfg.layers`` linear layers, orthogonal weights, no bias on the last layer) and the same
training recipe (``torch.optim.Adam`` with coupled L2 weight decay, a fresh random
minibatch each step), built with equinox and optax.

- Training is jit-compiled and stays on the device: one compiled call runs a whole log
  interval of optimizer steps with :func:`jax.lax.scan` and returns that interval's
  losses and the test loss, so the host only wakes up to log. The compilation is timed
  apart from training (``timings["compile_s"]``) and cached for the process, so later
  fits of the same shapes (other seeds, learning rates) compile nothing.
- Minibatch indices are drawn on the host with numpy (``Generator.choice`` without
  replacement, like torch's ``randperm(n)[:batch]``), one ``(steps, batch)`` block per
  interval, because XLA's CPU sort makes an on-device permutation of a large training
  set cost more than the training step itself.
- Rollouts use diffrax (Dopri5, PID step-size control) in float64. The batch of
  initial states is integrated as one system, as torchdiffeq does for the torch twins
  (one step-size sequence, error norm over the whole batch); this also compiles about
  twice as fast as a ``vmap`` of per-trajectory solves. A solve that stops early raises
  :class:`~hnnbench.errors.RolloutDiverged`; nothing is silently truncated.

Importing this module enables 64-bit floats in JAX (``jax_enable_x64``), which float64
rollouts need. Training runs in ``cfg.dtype``: parameters and data are cast explicitly.

It also turns on JAX's persistent compilation cache in
``$HNNBENCH_CACHE_DIR/jax-compilation`` (else the user cache dir; the ``cache_dir=``
setting does not move it, as it is chosen at import), unless
``JAX_COMPILATION_CACHE_DIR`` names another place or ``JAX_ENABLE_COMPILATION_CACHE=false``
turns it off. Launcher workers and later sweeps then load the rollout and training
executables other processes compiled instead of compiling them again. For the rollout
to be cacheable it must hold no host callbacks, so equinox's in-graph error checks
answer with NaN (``EQX_ON_ERROR=nan``, unless set otherwise) instead of calling back to
raise; a NaN rollout is recorded as diverged, like a solver failure.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar, Optional

import numpy as np

from hnnbench.api import Dataset, FitResult, Model, Progress, System, TrainSettings
from hnnbench.cache import cache_root
from hnnbench.errors import ConfigError, RolloutDiverged, require_backend
from hnnbench_plugins.models.neural import (
    BatchStream,
    NeuralConfig,
    init_arrays,
    mlp_shapes,
)

for _module in ("jax", "equinox", "optax", "diffrax"):
    require_backend(_module, "jax")

os.environ.setdefault("EQX_ON_ERROR", "nan")  # read when equinox is imported

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import optax  # noqa: E402

jax.config.update("jax_enable_x64", True)
if not jax.config.jax_compilation_cache_dir:
    jax.config.update("jax_compilation_cache_dir", str(cache_root() / "jax-compilation"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
# Probing for absent accelerators (TPU, GPU) logs an INFO line per backend, which the
# CLI's INFO-level logging would print on every run.
logging.getLogger("jax._src.xla_bridge").setLevel(logging.WARNING)

#: Format tag written into saved weight files.
WEIGHTS_FORMAT = "hnnbench-jax-mlp/1"

Field = Callable[["MLPNet", jax.Array], jax.Array]


# --------------------------------------------------------------------------- device


def _gpus() -> list[Any]:
    try:
        return list(jax.devices("gpu"))
    except RuntimeError:  # no GPU backend
        return []


def resolve_device(requested: str) -> Any:
    """``auto`` -> the first GPU if JAX sees one, else the CPU; ``cpu``; ``cuda[:N]``."""
    req = str(requested).strip().lower()
    if req == "auto":
        gpus = _gpus()
        return gpus[0] if gpus else jax.devices("cpu")[0]
    if req == "cpu":
        return jax.devices("cpu")[0]
    if req in ("cuda", "gpu") or req.startswith(("cuda:", "gpu:")):
        index = int(req.split(":", 1)[1]) if ":" in req and req.split(":", 1)[1].isdigit() else 0
        gpus = _gpus()
        if not gpus:
            raise ConfigError(
                f"device={requested} was requested but JAX sees no CUDA GPU: use device=cpu "
                "or device=auto (or install a CUDA build of jax)."
            )
        if index >= len(gpus):
            raise ConfigError(
                f"device={requested} was requested but JAX sees only {len(gpus)} GPU(s): "
                f"use device=cuda:0..{len(gpus) - 1}."
            )
        return gpus[index]
    raise ConfigError(f"device={requested} is invalid: expected auto, cpu, cuda or cuda:N.")


def device_name(device: Any) -> str:
    """Torch-style name of a JAX device: ``cpu`` or ``cuda:N``."""
    return "cpu" if device.platform == "cpu" else f"cuda:{device.id}"


# --------------------------------------------------------------------------- network

_ACTIVATIONS: dict[str, Callable[[jax.Array], jax.Array]] = {
    "tanh": jnp.tanh,
    "sigmoid": jax.nn.sigmoid,
    "softplus": jax.nn.softplus,
}


class Dense(eqx.Module):
    """``y = W x (+ b)`` on one input vector; ``weight`` is ``(out, in)`` as in torch."""

    weight: jax.Array
    bias: Optional[jax.Array]

    def __call__(self, x: jax.Array) -> jax.Array:
        y = self.weight @ x
        return y if self.bias is None else y + self.bias


class MLPNet(eqx.Module):
    """``len(linears)`` linear layers with an activation between them; the last has no
    bias. Maps one input vector ``(d_in,)`` to ``(d_out,)`` (``jax.vmap`` it for a
    batch). Parameter paths (``linears.0.weight``, ...) match the torch twin's
    ``state_dict`` keys."""

    linears: tuple[Dense, ...]
    activation: str = eqx.field(static=True)

    def __call__(self, x: jax.Array) -> jax.Array:
        act = _ACTIVATIONS[self.activation]
        h = x
        for layer in self.linears[:-1]:
            h = act(layer(h))
        return self.linears[-1](h)

    @property
    def d_in(self) -> int:
        return int(self.linears[0].weight.shape[1])

    @property
    def d_out(self) -> int:
        return int(self.linears[-1].weight.shape[0])


def _assemble(arrays: Mapping[str, Any], cfg: NeuralConfig, dtype: Any) -> MLPNet:
    linears = tuple(
        Dense(
            jnp.asarray(arrays[f"linears.{i}.weight"], dtype=dtype),
            None if i == cfg.layers - 1 else jnp.asarray(arrays[f"linears.{i}.bias"], dtype=dtype),
        )
        for i in range(cfg.layers)
    )
    return MLPNet(linears, cfg.activation)


def init_mlp(seed: int, d_in: int, d_out: int, cfg: NeuralConfig, dtype: Any = np.float64
             ) -> MLPNet:
    """A freshly initialised :class:`MLPNet` from :func:`~hnnbench_plugins.models.neural.
    init_arrays` (the same weights as the torch twin with this seed), cast to ``dtype``."""
    return _assemble(init_arrays(seed, d_in, d_out, cfg), cfg, dtype)


def _path_name(path: tuple[Any, ...]) -> str:
    """``(GetAttrKey('linears'), SequenceKey(0), GetAttrKey('weight'))`` -> ``linears.0.weight``."""
    parts = []
    for key in path:
        for attr in ("name", "idx", "key"):
            if hasattr(key, attr):
                parts.append(str(getattr(key, attr)))
                break
        else:
            parts.append(str(key))
    return ".".join(parts)


def net_to_numpy(net: MLPNet) -> dict[str, np.ndarray]:
    """The parameters as ``{tree path: array}``, e.g. ``{"linears.0.weight": ...}``."""
    leaves, _ = jax.tree_util.tree_flatten_with_path(net)
    return {_path_name(path): np.asarray(leaf) for path, leaf in leaves}


def net_from_numpy(
    state: Mapping[str, np.ndarray], cfg: NeuralConfig, dtype: Any = np.float64
) -> MLPNet:
    """Build an :class:`MLPNet` from ``{tree path: array}`` (as written by
    :func:`net_to_numpy`, or a torch ``state_dict`` converted to numpy: same keys,
    same shapes). The layout must match ``cfg`` (layers, hidden units)."""
    first = state.get("linears.0.weight")
    last = state.get(f"linears.{cfg.layers - 1}.weight")
    if first is None or last is None or np.ndim(first) != 2 or np.ndim(last) != 2:
        raise ValueError(
            f"weights do not describe a {cfg.layers}-layer MLP: expected keys "
            f"linears.0.weight .. linears.{cfg.layers - 1}.weight, got {sorted(state)}"
        )
    expected = mlp_shapes(int(np.shape(first)[1]), int(np.shape(last)[0]), cfg)
    if set(expected) != set(state):
        raise ValueError(
            f"weights do not match the model: missing {sorted(set(expected) - set(state))}, "
            f"unexpected {sorted(set(state) - set(expected))}"
        )
    for name, shape in expected.items():
        if np.shape(state[name]) != shape:
            raise ValueError(
                f"weight {name} has shape {np.shape(state[name])}, expected {shape} "
                f"(model.hidden={cfg.hidden}, model.layers={cfg.layers})"
            )
    return _assemble(state, cfg, dtype)


def cast(tree: Any, dtype: Any) -> Any:
    """Cast every floating-point array leaf of ``tree`` to ``dtype``."""
    return jax.tree.map(
        lambda a: a.astype(dtype) if eqx.is_inexact_array(a) else a, tree
    )


def symplectic(grad: jax.Array) -> jax.Array:
    """``(dH/dq, dH/dp) -> (dH/dp, -dH/dq)`` along the last axis."""
    n = grad.shape[-1] // 2
    return jnp.concatenate([grad[..., n:], -grad[..., :n]], axis=-1)


# --------------------------------------------------------------------------- compiled


@eqx.filter_jit
def _apply(fn: Field, net: MLPNet, x: jax.Array) -> jax.Array:
    return fn(net, x)


@eqx.filter_jit
def _solve(
    field: Field, net: MLPNet, y0: jax.Array, t: jax.Array, rtol: jax.Array, atol: jax.Array,
    max_steps: int,
) -> tuple[jax.Array, jax.Array]:
    """Dopri5 from the ``(M, D)`` batch ``y0`` over ``t``, the batch integrated as one
    system (one step size, error norm over all trajectories, as torchdiffeq does);
    returns ``ys (M, T, D)`` and the diffrax result code (0: success)."""
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda _t, y, _args: field(net, y)), diffrax.Dopri5(),
        t0=t[0], t1=t[-1], dt0=None, y0=y0, saveat=diffrax.SaveAt(ts=t),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps, throw=False,
    )
    return jnp.swapaxes(sol.ys, 0, 1), sol.result._value


def _result_message(code: int) -> str:
    try:
        return str(diffrax.RESULTS._index_to_message[code]).splitlines()[0]
    except (AttributeError, IndexError):  # private diffrax API moved
        return f"diffrax result code {code}"


# --------------------------------------------------------------------------- training


def adam_like_torch(lr: Any, weight_decay: Any) -> optax.GradientTransformation:
    """``torch.optim.Adam(lr, weight_decay=wd)`` in optax.

    torch adds ``wd * param`` to the gradient *before* the moment estimates (coupled L2,
    not AdamW's decoupled decay), and puts ``eps = 1e-8`` outside the square root of the
    bias-corrected second moment, as ``optax.adam`` does.
    """
    return optax.chain(
        optax.add_decayed_weights(weight_decay),
        optax.adam(lr, b1=0.9, b2=0.999, eps=1e-8, eps_root=0.0),
    )


def _train_chunk(
    field: Field, static: MLPNet, length: int, params: Any, opt_state: Any,
    idx: jax.Array | None, x: jax.Array, y: jax.Array, x_test: jax.Array, y_test: jax.Array,
    lr: jax.Array, weight_decay: jax.Array,
) -> tuple[Any, Any, jax.Array, jax.Array]:
    """One log interval: ``length`` optimizer steps under ``lax.scan``, then the test
    loss. ``idx`` holds ``(length, batch)`` minibatch indices, or is ``None`` (full
    batch). Returns the new params and optimizer state, the ``(length,)`` minibatch
    losses (each taken before its update, as torch logs them) and the test loss after the
    last update. ``lr`` and ``weight_decay`` are traced, so one executable serves every
    learning rate."""
    optimizer = adam_like_torch(lr, weight_decay)

    def loss_fn(params: Any, xb: jax.Array, yb: jax.Array) -> jax.Array:
        return jnp.mean((field(eqx.combine(params, static), xb) - yb) ** 2)

    params, opt_state, losses = scan_steps(loss_fn, optimizer, params, opt_state, idx, x, y,
                                           length)
    return params, opt_state, losses, loss_fn(params, x_test, y_test)


def scan_steps(
    loss_fn: Callable[[Any, jax.Array, jax.Array], jax.Array], optimizer: Any, params: Any,
    opt_state: Any, idx: jax.Array | None, x: jax.Array, y: jax.Array, length: int,
) -> tuple[Any, Any, jax.Array]:
    """``length`` optimizer steps of ``loss_fn(params, x_batch, y_batch)`` under
    ``lax.scan``; ``idx`` is ``(length, batch)`` minibatch indices or ``None`` (full
    batch). Returns the new params, optimizer state and the ``(length,)`` losses, each
    taken before its update."""

    def step(carry: tuple[Any, Any], batch_idx: jax.Array | None) -> Any:
        params, opt_state = carry
        xb, yb = (x, y) if batch_idx is None else (x[batch_idx], y[batch_idx])
        loss, grads = jax.value_and_grad(loss_fn)(params, xb, yb)
        updates, opt_state = optimizer.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), loss

    (params, opt_state), losses = jax.lax.scan(step, (params, opt_state), idx, length=length)
    return params, opt_state, losses


_train_chunk_jit = jax.jit(_train_chunk, static_argnums=(0, 1, 2))

#: Compiled training chunks of this process, keyed by model kind, network layout, chunk
#: length, argument shapes/dtypes and device: a sweep reuses them across seeds.
_COMPILED: dict[Any, Any] = {}
_COMPILED_MAX = 32


def _compiled_chunk(
    field: Field, static: Any, length: int, args: tuple, chunk: Any = None
) -> tuple[Any, float]:
    """The executable for one training chunk and the seconds spent compiling it (0.0
    when it was cached). ``chunk`` is the jitted chunk function (static arguments
    ``field, static, length``); default :func:`_train_chunk`."""
    chunk = _train_chunk_jit if chunk is None else chunk
    leaves, treedef = jax.tree_util.tree_flatten(args)
    avals = tuple((leaf.shape, str(leaf.dtype), str(leaf.sharding)) for leaf in leaves)
    key = (chunk, field, static, length, treedef, avals)
    if key in _COMPILED:
        return _COMPILED[key], 0.0
    start = time.perf_counter()
    with jax.default_matmul_precision("highest"):  # no TF32 on GPUs: as torch by default
        compiled = chunk.lower(field, static, length, *args).compile()
    seconds = time.perf_counter() - start
    if len(_COMPILED) >= _COMPILED_MAX:
        _COMPILED.pop(next(iter(_COMPILED)))
    _COMPILED[key] = compiled
    return compiled, seconds


# --------------------------------------------------------------------------- model


class JaxModel(Model):
    """Base of the JAX models: subclasses define ``field`` (and ``output_scalar``).

    Attributes:
        net: the trained :class:`MLPNet`, in the training dtype (``None`` before
            :meth:`fit` / :meth:`load`).
        initial_weights: if set (``{"linears.0.weight": ..., ...}``, e.g. a torch
            ``state_dict`` as numpy arrays), :meth:`fit` starts from these weights
            instead of a seeded random init. Used for warm starts and the cross-backend
            parity tests.
    """

    Config = NeuralConfig
    cfg: NeuralConfig
    backend = "jax"
    output_scalar: ClassVar[bool] = False

    def __init__(self, cfg: NeuralConfig, system: System, device: str = "auto") -> None:
        super().__init__(cfg, system, device)
        self._device = resolve_device(device)
        self._dtype = jnp.dtype(cfg.dtype)
        self.net: MLPNet | None = None
        self._net64: MLPNet | None = None
        self.initial_weights: Mapping[str, np.ndarray] | None = None

    @property
    def device(self) -> str:
        return device_name(self._device)

    # -- to implement ---------------------------------------------------------------
    @staticmethod
    def field(net: MLPNet, x: jax.Array) -> jax.Array:
        """``dx/dt`` ``(N, D)`` of a batch ``x`` ``(N, D)``; differentiable, jit-able."""
        raise NotImplementedError

    # -- network ----------------------------------------------------------------------
    def build(self, d_in: int, seed: int) -> MLPNet:
        """A seeded random net in the training dtype, on the model's device."""
        net = init_mlp(seed, d_in, 1 if self.output_scalar else d_in, self.cfg, self._dtype)
        return self._place(net)

    def _place(self, tree: Any) -> Any:
        return jax.device_put(tree, self._device)

    def _require_net(self) -> MLPNet:
        if self.net is None:
            raise RuntimeError(f"{self.name}: call fit() or load() first")
        return self.net

    def _set_net(self, net: MLPNet) -> None:
        if any(leaf.dtype != self._dtype for leaf in jax.tree.leaves(net)):
            net = cast(net, self._dtype)
        self.net, self._net64 = self._place(net), None

    def _float64_net(self) -> MLPNet:
        if self._net64 is None:
            self._net64 = cast(self._require_net(), jnp.float64)
        return self._net64

    def _array(self, x: Any, dtype: Any | None = None) -> jax.Array:
        return jax.device_put(jnp.asarray(np.asarray(x), dtype=dtype or self._dtype),
                              self._device)

    def numpy_layers(self) -> dict[str, np.ndarray]:
        """The current weights as ``{"linears.0.weight": array, ...}`` (torch naming)."""
        return net_to_numpy(self._require_net())

    def from_numpy_layers(self, state: Mapping[str, np.ndarray]) -> None:
        """Set the weights from ``{"linears.0.weight": array, ...}``: the keys and
        ``(out, in)`` shapes of the torch twin's ``state_dict``."""
        net = net_from_numpy(state, self.cfg, self._dtype)
        expected = 1 if self.output_scalar else net.d_in
        if net.d_out != expected:
            raise ValueError(
                f"{type(self).__name__} needs a network with {expected} output(s) for "
                f"{net.d_in} inputs; these weights have {net.d_out} (another model's?)"
            )
        self._set_net(net)

    def _chunk_plan(
        self, train: TrainSettings, n: int, seed: int
    ) -> tuple[list[int], Callable[[int], jax.Array | None]]:
        """How a fit of ``train.steps`` steps on ``n`` points is cut into compiled
        chunks (one per log interval): the chunk lengths, and a function that draws the
        next chunk's ``(length, batch)`` minibatch indices on the device (``None`` for
        full batch). Indices come from the run's shared :class:`BatchStream`."""
        full = train.batch_size is None or train.batch_size >= n
        stream = None if full else BatchStream(seed, n, int(train.batch_size))
        every = self.cfg.log_interval(train.steps)
        lengths = [every] * (train.steps // every)
        if train.steps % every:
            lengths.append(train.steps % every)

        def indices(length: int) -> jax.Array | None:
            if stream is None:
                return None
            return jax.device_put(jnp.asarray(stream.block(length), dtype=jnp.int32),
                                  self._device)

        return lengths, indices

    # -- training ---------------------------------------------------------------------
    def fit(
        self, data: Dataset, train: TrainSettings, seed: int, progress: Progress
    ) -> FitResult:
        x, dxdt = self._array(data.train.x), self._array(data.train.dxdt)
        x_test, dxdt_test = self._array(data.test.x), self._array(data.test.dxdt)
        if self.initial_weights is not None:
            self.from_numpy_layers(self.initial_weights)
            net = self._require_net()
        else:
            net = self.build(x.shape[1], seed)
        params, static = eqx.partition(net, eqx.is_inexact_array)
        opt_state = self._place(adam_like_torch(train.lr, train.weight_decay).init(params))
        hyper = (self._array(train.lr), self._array(train.weight_decay))  # training dtype

        lengths, indices = self._chunk_plan(train, int(x.shape[0]), seed)

        compile_s = 0.0
        history: dict[str, list[float]] = {"step": [], "train_loss": [], "test_loss": []}
        step = 0
        idx = indices(lengths[0])
        for k, length in enumerate(lengths):
            args = (params, opt_state, idx, x, dxdt, x_test, dxdt_test, *hyper)
            compiled, seconds = _compiled_chunk(self.field, static, length, args)
            compile_s += seconds
            params, opt_state, losses, test_loss = compiled(*args)
            if k + 1 < len(lengths):  # draw the next block while the device works
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
                self._set_net(eqx.combine(params, static))
                raise RolloutDiverged(f"training loss became {value} at step {at}")
        self.timings["compile_s"] = self.timings.get("compile_s", 0.0) + compile_s
        self._set_net(eqx.combine(params, static))
        return FitResult(history=history, steps=train.steps)

    # -- inference --------------------------------------------------------------------
    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        out = _apply(self.field, self._float64_net(), self._array(x, jnp.float64))
        return np.asarray(out, dtype=np.float64)

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        net = self._float64_net()
        y0 = self._array(np.atleast_2d(x0), jnp.float64)
        tt = self._array(t, jnp.float64)
        start = time.perf_counter()
        ys, codes = _solve(
            self.field, net, y0, tt, jnp.float64(rtol), jnp.float64(atol),
            int(self.cfg.rollout_max_steps),
        )
        out, codes = np.asarray(ys, dtype=np.float64), np.asarray(codes)
        self.timings["rollout_s"] = self.timings.get("rollout_s", 0.0) + (
            time.perf_counter() - start
        )
        if int(codes) != 0:
            finite = np.all(np.isfinite(out), axis=(0, 2))
            reached = float(t[np.flatnonzero(finite)[-1]]) if finite.any() else float(t[0])
            raise RolloutDiverged(
                f"dopri5 gave up after t={reached:g} (of {float(t[0]):g}..{float(t[-1]):g}): "
                f"{_result_message(int(codes))} (model.rollout_max_steps="
                f"{self.cfg.rollout_max_steps})"
            )
        if not np.all(np.isfinite(out)):
            raise RolloutDiverged("rollout produced non-finite states")
        return out

    # -- persistence ------------------------------------------------------------------
    def save(self, path: Path) -> None:
        """Write the weights to ``path`` as an ``.npz`` of arrays keyed by tree path
        (``linears.0.weight``, ...) plus a JSON header; no pickle."""
        net = self._require_net()
        arrays = net_to_numpy(net)
        meta = {"format": WEIGHTS_FORMAT, "model": type(self).__name__,
                "dtype": self.cfg.dtype, "activation": net.activation,
                "layers": len(net.linears), "hidden": self.cfg.hidden}
        arrays["__meta__"] = np.array(json.dumps(meta))
        with open(path, "wb") as fh:  # a handle: numpy must not append ".npz"
            np.savez(fh, **arrays)

    def load(self, path: Path) -> None:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in npz.files}
        meta = json.loads(str(arrays.pop("__meta__", "{}")))
        if meta.get("format") != WEIGHTS_FORMAT:
            raise ValueError(f"{path} is not a {WEIGHTS_FORMAT} weight file")
        if meta.get("activation", self.cfg.activation) != self.cfg.activation:
            raise ValueError(
                f"{path} was trained with activation={meta['activation']}, but the model "
                f"is configured with activation={self.cfg.activation}"
            )
        self.from_numpy_layers(arrays)
